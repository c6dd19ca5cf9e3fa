#include "firmware/loop/safety.hpp"

#include <signal.h>

#include <atomic>
#include <cstdlib>

#include "firmware/loop/controller.hpp"

namespace fs::fw {

namespace {
std::atomic<Laser*> g_laser{nullptr};
std::atomic<Galvo*> g_galvo{nullptr};
std::atomic<Controller*> g_controller{nullptr};

void on_crash(int sig) {
  force_safe();
  signal(sig, SIG_DFL);
  raise(sig);
}

void on_stop(int) {
  if (Controller* c = g_controller.load())
    c->request_stop();
  else {
    force_safe();
    _Exit(130);
  }
}

void at_exit_safe() { force_safe(); }
}  // namespace

void force_safe() noexcept {
  if (Laser* l = g_laser.load()) l->force_off();
  if (Galvo* g = g_galvo.load()) g->disable();
}

void install_safety_handlers(Laser* laser, Galvo* galvo, Controller* controller) {
  g_laser = laser;
  g_galvo = galvo;
  g_controller = controller;
  static bool registered = false;
  if (!registered) {
    registered = true;
    std::atexit(at_exit_safe);
  }
  struct sigaction sa {};
  sigemptyset(&sa.sa_mask);
  sa.sa_handler = on_crash;
  sa.sa_flags = SA_RESETHAND;
  for (int s : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) sigaction(s, &sa, nullptr);
  struct sigaction st {};
  sigemptyset(&st.sa_mask);
  st.sa_handler = on_stop;
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaction(s, &st, nullptr);
}

void clear_safety_handlers() {
  g_laser = nullptr;
  g_galvo = nullptr;
  g_controller = nullptr;
  for (int s : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGINT, SIGTERM, SIGHUP}) signal(s, SIG_DFL);
}

}  // namespace fs::fw
