// facetscan-fw(-hil) --check: the probes against the twins (sim, sim-can over a socketpair with
// the real SDO exchange) and the "missing device" messages for absent /dev nodes, chips, interfaces and
// drives.
#include <gtest/gtest.h>

#ifdef FACETSCAN_HAVE_BACKENDS
#include <unistd.h>

#include <sstream>
#include <string>

#include "common/error.hpp"
#include "firmware/app/devices.hpp"
#include "firmware/backends/device_check.hpp"
#include "firmware/backends/factory.hpp"
#include "firmware/fw_config.hpp"
#include "firmware/loop/monotonic_clock.hpp"
#include "hw-sim/can/cia402_twin.hpp"
#include "support/error_of.hpp"

namespace fs::test {
namespace {

using fw::CheckReport;

const fw::CheckItem* find_item(const CheckReport& r, const std::string& what_part) {
  for (const auto& i : r.items)
    if (i.what.find(what_part) != std::string::npos) return &i;
  return nullptr;
}

fw::FwConfig devices(const std::string& galvo, const std::string& camera) {
  fw::FwConfig c;
  c.galvo = galvo;
  c.camera = camera;
  return c;
}

// facetscan-fw-hil's check (hw-sim/devices_hil.cpp) takes the twins.
TEST(DeviceCheck, SimDevicesArePresent) {
  const CheckReport r = fw::check_configured_devices(devices("sim", "sim"));
  EXPECT_TRUE(r.ok()) << r.text();
  EXPECT_EQ(r.items.size(), 2u);
  EXPECT_NE(r.text().find("[ ok ] galvo: sim"), std::string::npos) << r.text();
}

TEST(DeviceCheck, SimCanReadsDeviceTypeAndStatuswordOverSdo) {
  const CheckReport r = fw::check_configured_devices(devices("sim-can:node=5", "sim"));
  ASSERT_TRUE(r.ok()) << r.text();
  const auto* dt = find_item(r, "device type (1000h)");
  ASSERT_NE(dt, nullptr) << r.text();
  EXPECT_NE(dt->what.find("node 5"), std::string::npos);
  EXPECT_NE(dt->detail.find("00020192h (CiA 402 drive)"), std::string::npos) << dt->detail;
  const auto* sw = find_item(r, "statusword (6041h)");
  ASSERT_NE(sw, nullptr) << r.text();
  EXPECT_NE(sw->detail.find("switch on disabled"), std::string::npos) << sw->detail;
}

// Without the HIL's checks (facetscan-fw, the board binary) the simulated devices are missing, naming the
// binary that has them.
TEST(DeviceCheck, BoardCheckSendsSimDevicesToTheHilBinary) {
  const CheckReport r = fw::check_devices("sim-can:node=5", "sim", "");
  EXPECT_EQ(r.failed(), 2u) << r.text();
  EXPECT_NE(r.text().find("[MISS] galvo: sim-can:node=5: a simulated device: those are in facetscan-fw-hil"),
            std::string::npos)
      << r.text();
  EXPECT_NE(r.text().find("[MISS] camera: sim:"), std::string::npos) << r.text();
  EXPECT_FALSE(fw::check_devices("sim", "v4l2:/dev/video99", "gpio:gpiochip99:line=1").ok());
}

TEST(DeviceCheck, DriveInFaultIsReported) {
  fw::MonotonicClock clock;
  const auto fds = fw::CanPort::socketpair_fds();
  fw::CanPort port(fds[0], true);
  sim::Cia402Twin twin(fds[1], clock);
  twin.inject_drive_fault(0x2310);
  CheckReport r;
  fw::check_can_drive(
      r, "galvo", "pair", port, 1, clock, [&] { twin.poll(); }, 300'000'000);
  ::close(fds[1]);
  EXPECT_FALSE(r.ok()) << r.text();
  const auto* sw = find_item(r, "statusword");
  ASSERT_NE(sw, nullptr) << r.text();
  EXPECT_FALSE(sw->ok);
  EXPECT_NE(sw->detail.find("fault"), std::string::npos) << sw->detail;
}

TEST(DeviceCheck, SilentDriveAndWrongNodeAreMissing) {
  fw::MonotonicClock clock;
  {
    const auto fds = fw::CanPort::socketpair_fds();  // nobody answers on the other end
    fw::CanPort port(fds[0], true);
    CheckReport r;
    fw::check_can_drive(r, "galvo", "pair", port, 1, clock, {}, 20'000'000);
    ::close(fds[1]);
    ASSERT_EQ(r.items.size(), 1u);
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.items[0].detail.find("no answer to the SDO read of 1000h within 20 ms"), std::string::npos)
        << r.text();
  }
  {
    const auto fds = fw::CanPort::socketpair_fds();
    fw::CanPort port(fds[0], true);
    sim::Cia402Twin twin(fds[1], clock);  // node 1; we ask node 7
    CheckReport r;
    fw::check_can_drive(
        r, "galvo", "pair", port, 7, clock, [&] { twin.poll(); }, 20'000'000);
    ::close(fds[1]);
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.text().find("node 7"), std::string::npos) << r.text();
  }
}

TEST(DeviceCheck, MissingDevicesAreNamed) {
  const CheckReport r =
      fw::check_devices("gpio:gpiochip99:step=17,dir=27,en=22,home=23,laser=24", "v4l2:/dev/video99", "");
  EXPECT_FALSE(r.ok());
  const std::string t = r.text();
  EXPECT_NE(
      t.find("[MISS] galvo: GPIO chip gpiochip99: cannot open /dev/gpiochip99: No such file or directory"),
      std::string::npos)
      << t;
  EXPECT_NE(t.find("[MISS] camera: V4L2 /dev/video99: cannot open /dev/video99: No such file or directory"),
            std::string::npos)
      << t;
  EXPECT_EQ(r.failed(), 2u) << t;

  const CheckReport c =
      fw::check_devices("can:nocan7:node=3", "v4l2:/dev/video99", "gpio:no-such-label:line=4");
  const std::string ct = c.text();
  EXPECT_NE(ct.find("[MISS] galvo: CAN interface nocan7: no network interface 'nocan7'"), std::string::npos)
      << ct;
  EXPECT_NE(ct.find("[MISS] laser: GPIO chip no-such-label: no GPIO chip labelled 'no-such-label'"),
            std::string::npos)
      << ct;
  EXPECT_EQ(c.failed(), 3u) << ct;
}

TEST(DeviceCheck, WrongKindOfDeviceAndMissingLaser) {
  const CheckReport r = fw::check_devices("gpio:/dev/null:step=1,dir=2,en=3,home=4", "v4l2:/dev/null", "");
  const std::string t = r.text();
  EXPECT_NE(t.find("/dev/null is not a GPIO chip"), std::string::npos) << t;
  EXPECT_NE(t.find("/dev/null is not a V4L2 device"), std::string::npos) << t;
  EXPECT_NE(t.find("[MISS] laser: (none): no laser line"), std::string::npos) << t;
  EXPECT_EQ(r.failed(), 3u) << t;
}

TEST(DeviceCheck, MalformedSpecsAreFailedItemsNamingTheKey) {
  const CheckReport r =
      fw::check_devices("can:can0:node=0", "v4l2:/dev/video0:fmt=RGB3", "gpio:gpiochip0:lin=3");
  EXPECT_EQ(r.failed(), 3u) << r.text();
  EXPECT_NE(r.text().find("node=0"), std::string::npos) << r.text();
  EXPECT_NE(r.text().find("RGB3"), std::string::npos) << r.text();
  EXPECT_NE(r.text().find("lin"), std::string::npos) << r.text();
  EXPECT_FALSE(fw::check_devices("steppers", "sim", "").ok());
}

TEST(DeviceCheck, LaserConfigKeyAndCanTimeoutKeys) {
  fw::FwConfig c;
  fw::apply_config_json(
      c, R"({"galvo": "can:can0", "camera": "v4l2:/dev/video0", "laser": "gpio:gpiochip0:line=24"})",
      "board.json");
  EXPECT_EQ(c.laser, "gpio:gpiochip0:line=24");
  try {
    fw::apply_config_json(c, R"({"laser": 24})", "board.json");
    ADD_FAILURE() << "a number for laser must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("board.json: laser: expected a string"), std::string::npos)
        << e.what();
  }
  // The gauss-ml noise model is configurable (a different camera / laser).
  fw::apply_config_json(
      c, R"({"extract": {"method": "gauss-ml", "read_noise": 3, "shot_noise": 0.5, "speckle": 0.2}})",
      "board.json");
  EXPECT_EQ(c.loop.extract.read_noise, 3.0);
  EXPECT_EQ(c.loop.extract.shot_noise, 0.5);
  EXPECT_EQ(c.loop.extract.speckle, 0.2);
  EXPECT_THROW(fw::apply_config_json(c, R"({"extract": {"speckle": -1}})", "board.json"), Error);
  // A numeric key: its default, values it takes, and values refused with an error naming the file and the
  // field that leave the last value in place.
  const auto expect_key = [&](const std::string& section, const std::string& key, auto get, auto dflt,
                              std::initializer_list<decltype(dflt)> good,
                              std::initializer_list<const char*> bad) {
    const auto json = [&](const std::string& v) {
      return "{\"" + section + "\": {\"" + key + "\": " + v + "}}";
    };
    EXPECT_EQ(get(), dflt) << key;
    for (const auto v : good) {
      std::ostringstream text;
      text << v;
      fw::apply_config_json(c, json(text.str()), "board.json");
      EXPECT_EQ(get(), v) << key;
    }
    const auto last = get();
    for (const char* v : bad) {
      const std::string e = test::error_of([&] { fw::apply_config_json(c, json(v), "board.json"); });
      EXPECT_NE(e.find("board.json: " + section + "." + key + ": "), std::string::npos) << v << ": " << e;
    }
    EXPECT_EQ(get(), last) << key << ": unchanged by the refused values";
  };
  // The along-stripe refinement: on by default (15 rows), 0 / 1 = off, odd 3..15.
  expect_key("extract", "along_stripe", [&] { return c.loop.extract.along_stripe; }, 15u, {5u, 0u},
             {"4", "17", "2.5", "\"on\""});
  // The software prefetch distance: 16 rows by default, 0 = off, at most 1024.
  expect_key("extract", "prefetch_rows", [&] { return c.loop.extract.prefetch_rows; }, 16u, {0u, 32u},
             {"1025", "-1", "1.5"});
  // The simulated camera's speckle grain: 0 (per pixel) by default, 0..8 px.
  expect_key("sim_camera", "speckle_grain_px", [&] { return c.sim_speckle_grain_px; }, 0.0, {1.5, 8.0},
             {"9", "-0.5", "\"fine\""});
  // A number beyond a double's range is a clear error naming the file, not a foreign exception (fuzz find).
  const std::string overflow =
      test::error_of([&] { fw::apply_config_json(c, R"({"sim_":4,"period_us":500e7777})", "board.json"); });
  EXPECT_NE(overflow.find("board.json: invalid JSON"), std::string::npos) << overflow;
  const fw::CanSpec s = fw::parse_can_spec("can:vcan0:node=2,sdo_ms=200,state_ms=5000");
  EXPECT_EQ(s.sdo_timeout_ms, 200u);
  EXPECT_EQ(s.state_timeout_ms, 5000u);
  EXPECT_THROW(fw::parse_can_spec("can:vcan0:sdo_ms=0"), Error);
}

}  // namespace
}  // namespace fs::test
#endif
