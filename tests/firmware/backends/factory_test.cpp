// Device spec parsing (the facetscan-fw --galvo / --camera flags) and the error paths of opening devices that
// are not there.
#include <gtest/gtest.h>

#include "common/error.hpp"
#include "firmware/backends/factory.hpp"
#include "firmware/backends/gpiod_lines.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "hw-sim/can/sim_can_galvo.hpp"
#include "support/error_of.hpp"
#include "test_clock.hpp"

namespace fs::test {
namespace {

using fs::test::error_of;

TEST(BackendSpecs, GpioByOffsetsAndNames) {
  auto g = fw::parse_gpio_spec("gpio:gpiochip1:step=0,dir=1,en=2,home=3,laser=4,home_active_low=1");
  EXPECT_EQ(g.chip, "gpiochip1");
  EXPECT_EQ(g.step.offset, 0);
  EXPECT_EQ(g.dir.offset, 1);
  EXPECT_EQ(g.enable.offset, 2);
  EXPECT_EQ(g.home.offset, 3);
  EXPECT_EQ(g.laser.offset, 4);
  EXPECT_TRUE(g.home_active_low);
  EXPECT_FALSE(g.enable_active_low);
  g = fw::parse_gpio_spec(
      "gpio:/dev/gpiochip0:step=GALVO_STEP,dir=GALVO_DIR,en=EN,home=HOME,en_active_low=1");
  EXPECT_EQ(g.chip, "/dev/gpiochip0");
  EXPECT_EQ(g.step.name, "GALVO_STEP");
  EXPECT_EQ(g.step.offset, -1);
  EXPECT_FALSE(g.laser.valid());
  EXPECT_TRUE(g.enable_active_low);
}

TEST(BackendSpecs, GpioErrorsNameTheProblem) {
  EXPECT_NE(error_of([] { fw::parse_gpio_spec("gpio:chip:step=0,dir=1,en=2"); }).find("missing line 'home='"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              fw::parse_gpio_spec("gpio:chip:step=0,dir=1,en=2,home=3,foo=1");
            }).find("unknown key 'foo'"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_gpio_spec("gpio:chip:step=0,dir=0,en=2,home=3"); }).find("twice"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_gpio_spec("gpio:chip:step=0,step=1,en=2,home=3"); }).find("given twice"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_gpio_spec("gpio:chip:step"); }).find("expected key=value"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_gpio_spec("gpio:chip"); }).find("expected gpio:CHIP"), std::string::npos);
  EXPECT_NE(error_of([] {
              fw::parse_gpio_spec("gpio:chip:step=0,dir=1,en=2,home=3,home_active_low=2");
            }).find("not a boolean"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_gpio_spec("gpio::step=0"); }).find("empty field"), std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_gpio_spec("gpio:c:step=99999,dir=1,en=2,home=3"); }).find("out of range"),
            std::string::npos);
}

TEST(BackendSpecs, Can) {
  auto c = fw::parse_can_spec("can:can0:node=5,hb=50,vel=1000,acc=2000");
  EXPECT_EQ(c.iface, "can0");
  EXPECT_EQ(c.node, 5);
  EXPECT_EQ(c.heartbeat_ms, 50);
  EXPECT_EQ(c.velocity, 1000u);
  EXPECT_EQ(c.acceleration, 2000u);
  c = fw::parse_can_spec("can:vcan0");
  EXPECT_EQ(c.node, 1);
  c = fw::parse_can_spec("sim-can");
  EXPECT_TRUE(c.iface.empty());
  c = fw::parse_can_spec("sim-can:node=9");
  EXPECT_EQ(c.node, 9);
  EXPECT_NE(error_of([] { fw::parse_can_spec("can:can0:node=0"); }).find("node=0 out of range 1..127"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_can_spec("can:can0:node=x"); }).find("not an integer"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_can_spec("can:averyveryverylongname"); }).find("longer than 15"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_can_spec("cam:can0"); }).find("can:IFACE"), std::string::npos);
}

TEST(BackendSpecs, V4l2) {
  auto v = fw::parse_v4l2_spec("v4l2:/dev/video0");
  EXPECT_EQ(v.device, "/dev/video0");
  EXPECT_EQ(v.format, fw::V4l2Fourcc::Grey);
  v = fw::parse_v4l2_spec("v4l2:/dev/video2:fmt=Y16,width=640,height=480,fps=60,exposure=50,buffers=8");
  EXPECT_EQ(v.format, fw::V4l2Fourcc::Y16);
  EXPECT_EQ(v.width, 640u);
  EXPECT_EQ(v.height, 480u);
  EXPECT_EQ(v.fps, 60u);
  EXPECT_EQ(v.exposure, 50);
  EXPECT_EQ(v.buffers, 8u);
  EXPECT_EQ(fw::parse_v4l2_spec("v4l2:/dev/video2:fmt=YUYV").format, fw::V4l2Fourcc::Yuyv);
  EXPECT_NE(error_of([] { fw::parse_v4l2_spec("v4l2:/dev/video0:fmt=MJPG"); }).find("known: GREY, Y16, YUYV"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_v4l2_spec("v4l2:/dev/video0:buffers=2"); }).find("out of range 4..32"),
            std::string::npos);
}

TEST(BackendSpecs, GpioLaser) {
  auto l = fw::parse_gpio_laser_spec("gpio:gpiochip2:line=7,active_low=1");
  EXPECT_EQ(l.chip, "gpiochip2");
  EXPECT_EQ(l.line.offset, 7);
  EXPECT_TRUE(l.active_low);
  EXPECT_EQ(fw::parse_gpio_laser_spec("gpio:lbl:line=LASER_EN").line.name, "LASER_EN");
  EXPECT_NE(error_of([] { fw::parse_gpio_laser_spec("gpio:c:active_low=1"); }).find("missing 'line='"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::parse_gpio_laser_spec("gpio:c:line=1,step=2"); }).find("unknown key 'step'"),
            std::string::npos);
  EXPECT_NE(error_of([] { fw::make_gpio_laser("gpio:gpiochip97:line=1"); }).find("gpiochip97"),
            std::string::npos);
}

TEST(BackendOpen, MissingDevicesGiveClearErrors) {
  const std::string gpio =
      error_of([] { fw::make_gpio_backend("gpio:gpiochip97:step=0,dir=1,en=2,home=3"); });
  EXPECT_NE(gpio.find("gpiochip97"), std::string::npos) << gpio;
  const std::string can = error_of([] { fw::make_can_galvo("can:nosuchcan9"); });
  EXPECT_NE(can.find("nosuchcan9"), std::string::npos) << can;
  const std::string cam = error_of([] { fw::make_v4l2_camera("v4l2:/dev/video97"); });
  EXPECT_NE(cam.find("/dev/video97"), std::string::npos) << cam;
  EXPECT_NE(cam.find("cannot open"), std::string::npos) << cam;
}

TEST(BackendOpen, SimCanGalvoEnablesAndMovesOnAManualClock) {
  ManualClock clock;
  auto b = sim::make_sim_can_galvo("sim-can:node=4", clock);
  ASSERT_NE(b.twin, nullptr);
  double last_pos = -1;
  b.twin->set_position_callback([&](double p, std::int64_t) { last_pos = p; });
  b.galvo->enable(clock.now());
  fw::GalvoStatus s;
  for (int i = 0; i < 300 && !s.enabled; ++i) {
    clock.advance(kMs);
    s = b.galvo->poll(clock.now());
  }
  ASSERT_TRUE(s.enabled);
  b.galvo->move_to(2500, clock.now());
  for (int i = 0; i < 1000; ++i) {
    clock.advance(kMs);
    s = b.galvo->poll(clock.now());
    if (s.in_position) break;
  }
  EXPECT_TRUE(s.in_position);
  EXPECT_EQ(s.measured_step, 2500.0);
  EXPECT_EQ(last_pos, 2500.0);
  b.galvo->disable();
  EXPECT_EQ(b.twin->state(), cia402::DriveState::SwitchOnDisabled);
}

TEST(BackendOpen, GpiodApiVersionMatchesTheBuild) {
  EXPECT_EQ(fw::GpiodLines::api_version(), FACETSCAN_GPIOD_API);
}

}  // namespace
}  // namespace fs::test
