#pragma once
// Test helper: one scene renderer (hw-sim/scene/stripe_renderer.hpp) and the firmware's stripe extractor
// wired to one camera frame buffer. step() draws a galvo step and extracts its stripe; the renderer's true 3D
// point of every row stays available through renderer().truth() until the next step.
#include <cstdint>
#include <span>
#include <vector>

#include "firmware/extract/stripe_extractor.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"

namespace fs::test {

class RenderExtract {
 public:
  RenderExtract(const sim::Scene& scene, double noise_scale, const fw::ExtractParams& params = {})
      : params_(params),
        renderer_(scene, options(noise_scale)),
        image_(std::size_t(scene.calibration.camera.width) * scene.calibration.camera.height),
        points_(scene.calibration.camera.height) {
    const auto& cam = scene.calibration.camera;
    fb_ = sim::FrameBuffer{image_.data(), cam.width, cam.height, cam.width, sim::FrameFormat::Mono8};
    fv_.data = image_.data();
    fv_.width = cam.width;
    fv_.height = cam.height;
    fv_.stride = cam.width;
    fv_.format = fw::PixelFormat::Mono8;
  }

  // Renders galvo step `step` with the noise seed and extracts it (the constructor's extraction parameters,
  // default: the firmware's).
  fw::ExtractCounts step(std::uint32_t step, std::uint64_t seed) {
    renderer_.render_step(step, seed, fb_);
    return fw::extract_frame(fv_, params_, points_);
  }
  // The stripe points of the last step (counts.points of them are valid).
  std::span<const msg::StripePoint> points(const fw::ExtractCounts& counts) const {
    return std::span(points_.data(), counts.points);
  }
  const sim::StripeRenderer& renderer() const { return renderer_; }

 private:
  fw::ExtractParams params_;
  static sim::RenderOptions options(double noise_scale) {
    sim::RenderOptions ro;
    ro.noise_scale = noise_scale;
    return ro;
  }
  sim::StripeRenderer renderer_;
  std::vector<std::uint8_t> image_;
  sim::FrameBuffer fb_;
  fw::FrameView fv_;
  std::vector<msg::StripePoint> points_;
};

}  // namespace fs::test
