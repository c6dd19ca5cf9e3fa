// libgpiod 2.x check, run inside the VM: GpiodLines built from gpiod_lines_v2.cpp (the v2 API backend)
// against libgpiod 2.1 from bookworm-backports (fetched by run_vm.sh into the build directory), on the
// gpio-sim chip. Prints "GPIOD2 PASS" or the first failure; exit status 0 only on success.
#include <time.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "common/error.hpp"
#include "firmware/backends/gpiod_lines.hpp"

namespace {

std::string slurp(const std::string& p) {
  std::ifstream in(p);
  std::string s;
  std::getline(in, s);
  return s;
}
int failures = 0;
#define CHECK(c)                                               \
  do {                                                         \
    if (!(c)) {                                                \
      std::printf("GPIOD2 FAIL %s (line %d)\n", #c, __LINE__); \
      ++failures;                                              \
    }                                                          \
  } while (0)

}  // namespace

int main() {
  using namespace fs::fw;
  const std::string cfg = "/sys/kernel/config/gpio-sim/facetscan";
  const std::string sys =
      "/sys/devices/platform/" + slurp(cfg + "/dev_name") + "/" + slurp(cfg + "/bank0/chip_name");
  auto value = [&](int i) { return std::stoi(slurp(sys + "/sim_gpio" + std::to_string(i) + "/value")); };
  auto pull = [&](int i, const char* v) {
    std::ofstream(sys + "/sim_gpio" + std::to_string(i) + "/pull") << v;
  };
  try {
    CHECK(GpiodLines::api_version() == 2);
    GpioSpec spec;
    spec.chip = "facetscan-sim";  // by label
    spec.step.name = "STEP";
    spec.dir.offset = 1;
    spec.enable.name = "EN";
    spec.home.offset = 3;
    spec.laser.offset = 4;
    spec.enable_active_low = true;
    auto lines = GpiodLines::open(spec);
    std::printf("GPIOD2 %s\n", lines->describe().c_str());
    CHECK(value(2) == 1);
    int rising = 0, last = 0;
    for (int i = 0; i < 100; ++i) {
      lines->set_step(true, 0);
      int v = value(0);
      if (v == 1 && last == 0) ++rising;
      last = v;
      lines->set_step(false, 0);
      last = value(0);
    }
    CHECK(rising == 100);
    CHECK(lines->step_pulses() == 100);
    lines->set_enable(true, 0);
    CHECK(value(2) == 0);
    GpioEdge e;
    while (lines->next_home_edge(e)) {
    }
    const Nanos before = monotonic_now();
    pull(3, "pull-up");
    bool got = false;
    for (int i = 0; i < 500 && !(got = lines->next_home_edge(e)); ++i) {
      timespec ts{0, 1'000'000};
      nanosleep(&ts, nullptr);
    }
    CHECK(got && e.rising && e.timestamp >= before);
    CHECK(lines->read_home(0));
    pull(3, "pull-down");
    got = false;
    for (int i = 0; i < 500 && !(got = lines->next_home_edge(e)); ++i) {
      timespec ts{0, 1'000'000};
      nanosleep(&ts, nullptr);
    }
    CHECK(got && !e.rising);
    lines->set_laser(true, 0);
    CHECK(value(4) == 1);
    lines->safe();
    CHECK(value(4) == 0 && value(2) == 1 && value(0) == 0);
    bool refused = false;
    try {
      GpiodLines::open(spec);
    } catch (const fs::Error& err) {
      refused = std::string(err.what()).find("one request") != std::string::npos;
    }
    CHECK(refused);
    {
      GpioLaserSpec ls;
      ls.chip = sys.substr(sys.rfind('/') + 1);  // gpiochipN
      ls.line.offset = 5;
      auto laser = open_gpiod_laser(ls);
      CHECK(value(5) == 0);
      laser->set(true, 0);
      CHECK(value(5) == 1 && laser->is_on());
    }
    CHECK(value(5) == 0);
  } catch (const std::exception& ex) {
    std::printf("GPIOD2 FAIL exception: %s\n", ex.what());
    ++failures;
  }
  std::printf(failures ? "GPIOD2 FAILED (%d)\n" : "GPIOD2 PASS\n", failures);
  return failures ? 1 : 0;
}
