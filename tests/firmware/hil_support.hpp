#pragma once
// Test rig: the controller loop on the hw-sim twins (virtual time) publishing into memory, and a decoder of
// the published wire stream.
#include <memory>
#include <string>
#include <vector>

#include "common/wire.hpp"
#include "firmware/loop/controller.hpp"
#include "firmware/stream/queued_publisher.hpp"
#include "hw-sim/sim_rig.hpp"
#include "hw-sim/table_renderer.hpp"

namespace fs::test {

// A reduced camera (320 x 256) so that ASan runs stay fast; the geometry is the bench default's.
inline ScannerCalibration small_calibration(std::uint32_t steps) {
  ScannerCalibration c = ScannerCalibration::bench_default(steps);
  c.camera.width = 320;
  c.camera.height = 256;
  c.camera.fx = c.camera.fy = 400.0;
  c.camera.cx = 159.5;
  c.camera.cy = 127.5;
  return c;
}

struct Decoded {
  std::vector<msg::StripeHeader> stripes;
  std::vector<std::vector<msg::StripePoint>> points;
  std::vector<msg::Fault> faults;
  std::vector<msg::Heartbeat> heartbeats;
  std::vector<msg::ScanEnd> ends;
  int scan_begins = 0;
};

inline Decoded decode_all(std::span<const std::uint8_t> bytes) {
  Decoded d;
  wire::FrameDecoder dec("hil");
  wire::DecodedMessage m;
  wire::FrameView f;
  while (!bytes.empty()) {
    bytes = bytes.subspan(dec.feed(bytes));
    while (dec.next(f)) {
      wire::decode(f, m, "hil");
      switch (m.type) {
        case msg::Type::ScanBegin:
          ++d.scan_begins;
          break;
        case msg::Type::Stripe:
          d.stripes.push_back(m.stripe.header);
          d.points.emplace_back(m.stripe.points.begin(), m.stripe.points.end());
          break;
        case msg::Type::ScanEnd:
          d.ends.push_back(m.scan_end);
          break;
        case msg::Type::Heartbeat:
          d.heartbeats.push_back(m.heartbeat);
          break;
        case msg::Type::Fault:
          d.faults.push_back(m.fault);
          break;
      }
    }
  }
  dec.finish();
  return d;
}

struct Hil {
  explicit Hil(std::uint32_t steps, std::vector<std::string> faults = {}, fw::LoopConfig cfg = {},
               sim::RigConfig rig_cfg = {})
      : cal(small_calibration(steps)), renderer(cal), rig(renderer, [&] {
          rig_cfg.faults = std::move(faults);
          return rig_cfg;
        }()) {
    fw::QueuedPublisherConfig pc;
    pc.block_when_full = true;
    pc.max_points = cal.camera.height;
    pub = std::make_unique<fw::QueuedPublisher>(sink, pc);
    cfg.steps = steps;
    cfg.first_step = 0;
    cfg.max_rows = cal.camera.height;
    ctl = std::make_unique<fw::Controller>(fw::Devices{rig.clock, rig.galvo, rig.laser, rig.camera}, cfg,
                                           *pub, cal);
  }
  Decoded decoded() {
    pub->flush();
    return decode_all(sink.data);
  }
  ScannerCalibration cal;
  sim::TableStripeRenderer renderer;
  sim::SimRig rig;
  wire::VectorSink sink;
  std::unique_ptr<fw::QueuedPublisher> pub;
  std::unique_ptr<fw::Controller> ctl;
};

}  // namespace fs::test
