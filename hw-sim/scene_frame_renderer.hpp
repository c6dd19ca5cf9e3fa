#pragma once
// The scene renderer (hw-sim/scene/) behind the camera twin's FrameRenderer interface: frames of a loaded
// scene for the mirror position at exposure time, the laser power scaled by the fraction of the exposure the
// laser emitted (and by the glare gain of the saturated-frame fault). Ground truth per row from the scene's
// stripe tracer.
#include <vector>

#include "hw-sim/frame_renderer.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"
#include "hw-sim/scene/stripe_tracer.hpp"

namespace fs::sim {

class SceneFrameRenderer final : public FrameRenderer {
 public:
  // `scene` must outlive the renderer.
  explicit SceneFrameRenderer(const Scene& scene, const RenderOptions& options = {});
  std::uint32_t width() const override { return scene_.calibration.camera.width; }
  std::uint32_t height() const override { return scene_.calibration.camera.height; }
  void render(const RenderRequest& req, std::span<std::uint8_t> pixels, std::uint32_t stride) override;
  void truth(double mirror_step, std::span<double> col_per_row) override;
  // Full ground truth (3D point, object, face) per row for a mirror position.
  std::span<const StripeSample> truth_samples(double mirror_step);

 private:
  const Scene& scene_;
  StripeRenderer renderer_;
  StripeTracer tracer_;
  double base_peak_;
  std::vector<StripeSample> rows_;
};

}  // namespace fs::sim
