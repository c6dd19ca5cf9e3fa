// Process crash / exit: the safety handlers drive the laser line to its safe level. A child process with a
// laser that reports force_off() through a pipe crashes (SIGABRT) or exits; the parent checks the report.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>

#include "firmware/loop/safety.hpp"

namespace fs::fw {
namespace {

class PipeLaser final : public Laser {
 public:
  explicit PipeLaser(int fd) : fd_(fd) {}
  void set(bool on, Nanos) override { on_ = on; }
  bool is_on() const override { return on_; }
  void force_off() noexcept override {
    on_ = false;
    const char c = 'L';
    [[maybe_unused]] auto r = ::write(fd_, &c, 1);
  }

 private:
  int fd_;
  bool on_ = false;
};

class PipeGalvo final : public Galvo {
 public:
  explicit PipeGalvo(int fd) : fd_(fd) {}
  void enable(Nanos) override {}
  void start_homing(Nanos) override {}
  void move_to(std::int32_t, Nanos) override {}
  GalvoStatus poll(Nanos) override { return {}; }
  void reset_fault(Nanos) override {}
  void disable() noexcept override {
    const char c = 'G';
    [[maybe_unused]] auto r = ::write(fd_, &c, 1);
  }

 private:
  int fd_;
};

std::string run_child(int how) {
  int p[2];
  EXPECT_EQ(pipe(p), 0);
  const pid_t pid = fork();
  if (pid == 0) {
    close(p[0]);
    PipeLaser laser(p[1]);
    PipeGalvo galvo(p[1]);
    install_safety_handlers(&laser, &galvo, nullptr);
    laser.set(true, 0);
    if (how == 0) std::abort();      // crash
    if (how == 1) std::exit(3);      // exit without cleanup of the stack objects
    if (how == 2) ::raise(SIGTERM);  // stop signal without a controller: safe + exit 130
    _exit(0);
  }
  close(p[1]);
  std::string got;
  char buf[16];
  ssize_t n;
  while ((n = read(p[0], buf, sizeof buf)) > 0) got.append(buf, static_cast<std::size_t>(n));
  close(p[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  const bool ok = how == 0   ? (WIFSIGNALED(status) && WTERMSIG(status) == SIGABRT)
                  : how == 1 ? (WIFEXITED(status) && WEXITSTATUS(status) == 3)
                             : (WIFEXITED(status) && WEXITSTATUS(status) == 130);
  EXPECT_TRUE(ok) << "child status " << status;
  return got;
}

TEST(Safety, CrashForcesLaserOff) { EXPECT_EQ(run_child(0).substr(0, 2), "LG"); }
TEST(Safety, ExitForcesLaserOff) { EXPECT_EQ(run_child(1).substr(0, 2), "LG"); }
TEST(Safety, TermSignalForcesLaserOff) { EXPECT_EQ(run_child(2).substr(0, 2), "LG"); }

}  // namespace
}  // namespace fs::fw
