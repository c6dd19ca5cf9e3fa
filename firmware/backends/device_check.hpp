#pragma once
// `facetscan-fw --check`: probes the configured devices without moving anything and reports what is found and
// what is missing.
//   GPIO  (gpio:... galvo / laser): the chip (by path, gpiochipN, number or label) through the kernel GPIO
//         character device, every line (offset or name) present and not used by another consumer.
//   CAN   (can:IFACE...): the interface exists and is up, the drive answers an SDO read of 0x1000 (device
//   type)
//         and 0x6041 (statusword); a heartbeat seen meanwhile gives its NMT state.
//   V4L2  (v4l2:/dev/videoN...): the node opens, is a streaming capture device, its formats (VIDIOC_ENUM_FMT)
//         include the configured one, and VIDIOC_TRY_FMT keeps the configured size.
//   sim, sim-can, --camera sim: checked by the caller's SimChecks (facetscan-fw-hil, hw-sim/devices_hil.cpp:
//         the same CAN probe against the drive twin over a socketpair); without them a failed item naming
//         facetscan-fw-hil (the board binary has no simulated devices).
// Nothing here throws for a missing device: each problem is one failed item with a message naming the device.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "firmware/backends/can_port.hpp"
#include "firmware/backends/factory.hpp"
#include "firmware/device/clock.hpp"

namespace fs::fw {

struct CheckItem {
  std::string device;  // "galvo", "camera", "laser"
  std::string what;    // what was probed, e.g. "GPIO chip gpiochip0", "CAN drive node 1 on vcan0"
  bool ok = false;
  std::string detail;  // what was found, or why it is missing
};

struct CheckReport {
  std::vector<CheckItem> items;
  bool ok() const;
  std::size_t failed() const;
  std::string text() const;  // one line per item: "  [ ok ] galvo: ...: ..." / "  [MISS] ..."
  void add(std::string device, std::string what, bool ok, std::string detail);
};

// GPIO chip + lines. `lines` = (role, reference) pairs, e.g. ("step", {17}).
void check_gpio(CheckReport& r, const std::string& device, const std::string& chip,
                const std::vector<std::pair<std::string, GpioLineRef>>& lines);
// The CiA 402 drive `node` behind `port` (no frame but SDO uploads is sent). `service` runs between reads
// (the twin's poll for sim-can; may be empty). Waits up to `timeout` per request on `clock`.
void check_can_drive(CheckReport& r, const std::string& device, const std::string& label, CanPort& port,
                     std::uint8_t node, Clock& clock, const std::function<void()>& service, Nanos timeout);
void check_v4l2(CheckReport& r, const std::string& device, const V4l2Spec& spec);

// The specs of the simulated devices: galvo sim / sim-can[:...], camera sim.
bool is_sim_galvo(const std::string& spec);
bool is_sim_camera(const std::string& spec);

// Checks of the simulated devices (given by facetscan-fw-hil): each adds the items of its spec.
struct SimChecks {
  std::function<void(CheckReport&, const std::string&)> galvo, camera;  // (report, spec)
};

// All configured devices from the facetscan-fw spec strings (gpio:, can:, v4l2:, laser gpio:; sim, sim-can
// and camera sim through `sim`). A malformed spec is a failed item too (the message of the parser).
CheckReport check_devices(const std::string& galvo, const std::string& camera, const std::string& laser,
                          const SimChecks& sim = {});

}  // namespace fs::fw
