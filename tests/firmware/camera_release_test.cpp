// The controller must not hand a frame back to a camera it has just stopped (scan Done, or a fault raised
// while handling that frame): a real V4L2 camera refuses it ("release of buffer N that is not handed out"),
// which the VM scan through v4l2loopback found. StrictCamera enforces the V4L2 rules on top of the twin.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "hil_support.hpp"

namespace fs::test {
namespace {

class StrictCamera final : public fw::Camera {
 public:
  explicit StrictCamera(fw::Camera& c) : c_(c) {}
  void start(fw::Nanos now) override {
    running_ = true;
    c_.start(now);
  }
  void stop() noexcept override {
    running_ = false;
    out_.clear();
    c_.stop();
  }
  fw::GrabResult grab(fw::Nanos deadline, fw::FrameView& f) override {
    if (!running_) ++bad_;
    const fw::GrabResult r = c_.grab(deadline, f);
    if (r == fw::GrabResult::Ok) out_.insert(f.buffer);
    return r;
  }
  void release(const fw::FrameView& f) override {
    if (!running_ || out_.erase(f.buffer) == 0) {
      ++bad_;
      return;
    }
    c_.release(f);
  }
  std::uint32_t frames_dropped() const override { return c_.frames_dropped(); }
  int bad_ = 0;

 private:
  fw::Camera& c_;
  bool running_ = false;
  std::set<int> out_;
};

struct ScanResult {
  fw::State state;
  fw::FaultCode fault;
  int bad;
};

ScanResult scan(std::vector<std::string> faults) {
  const ScannerCalibration cal = small_calibration(12);
  sim::TableStripeRenderer renderer(cal);
  sim::RigConfig rc;
  rc.faults = std::move(faults);
  sim::SimRig rig(renderer, rc);
  StrictCamera cam(rig.camera);
  wire::VectorSink sink;
  fw::QueuedPublisherConfig pc;
  pc.block_when_full = true;
  pc.max_points = cal.camera.height;
  fw::QueuedPublisher pub(sink, pc);
  fw::LoopConfig cfg;
  cfg.steps = 12;
  cfg.max_rows = cal.camera.height;
  fw::Controller ctl(fw::Devices{rig.clock, rig.galvo, rig.laser, cam}, cfg, pub, cal);
  const auto& r = ctl.run();
  pub.flush();
  return {r.state, r.fault, cam.bad_};
}

TEST(ControllerCamera, NoReleaseAfterTheScanStopsTheCamera) {
  const ScanResult r = scan({});
  EXPECT_EQ(r.state, fw::State::Done);
  EXPECT_EQ(r.bad, 0) << "frames released to (or grabbed from) a stopped camera";
}

TEST(ControllerCamera, NoReleaseAfterAFaultInTheFrameHandlerStopsTheCamera) {
  const ScanResult r = scan({"camera.saturate@frame=5,count=20"});
  EXPECT_EQ(r.state, fw::State::Fault);
  EXPECT_EQ(r.fault, fw::FaultCode::FrameSaturated);
  EXPECT_EQ(r.bad, 0);
}

}  // namespace
}  // namespace fs::test
