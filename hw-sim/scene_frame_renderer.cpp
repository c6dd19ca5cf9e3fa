#include "hw-sim/scene_frame_renderer.hpp"

#include <algorithm>

namespace fs::sim {

SceneFrameRenderer::SceneFrameRenderer(const Scene& scene, const RenderOptions& options)
    : scene_(scene),
      renderer_(scene, options),
      tracer_(scene),
      base_peak_(options.laser_peak),
      rows_(scene.calibration.camera.height) {}

void SceneFrameRenderer::render(const RenderRequest& req, std::span<std::uint8_t> pixels,
                                std::uint32_t stride) {
  renderer_.options().laser_peak = base_peak_ * std::clamp(req.laser_fraction, 0.0, 1.0) * req.gain;
  FrameBuffer fb;
  fb.data = pixels.data();
  fb.width = width();
  fb.height = height();
  fb.stride = stride;
  fb.format = FrameFormat::Mono8;
  renderer_.render_step(req.mirror_step, req.seed, fb);
}

std::span<const StripeSample> SceneFrameRenderer::truth_samples(double mirror_step) {
  tracer_.trace_mirror_angle(scene_.calibration.laser.mirror_angle(mirror_step), rows_);
  return rows_;
}

void SceneFrameRenderer::truth(double mirror_step, std::span<double> out) {
  truth_samples(mirror_step);
  for (std::size_t i = 0; i < out.size() && i < rows_.size(); ++i) out[i] = rows_[i].column;
}

}  // namespace fs::sim
