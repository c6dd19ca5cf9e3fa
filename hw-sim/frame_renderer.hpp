#pragma once
// What the camera twin needs from a renderer: a stripe image for a mirror position (galvo steps) and laser
// power, plus the true stripe centre per row for that position (ground truth for tests).
// Implementations: TableStripeRenderer (hw-sim/table_renderer.hpp: the laser on the bare table, analytic,
// no scene) and the scene renderer adapter (hw-sim/scene_frame_renderer.hpp).
#include <cstdint>
#include <span>

namespace fs::sim {

struct RenderRequest {
  double mirror_step = 0.0;     // galvo position at mid-exposure (steps, fractional)
  double laser_fraction = 1.0;  // fraction of the exposure the laser emitted (0..1)
  double gain = 1.0;            // > 1 for glare (saturated-frame fault)
  std::uint64_t seed = 0;       // noise seed (the frame sequence number)
};

class FrameRenderer {
 public:
  virtual ~FrameRenderer() = default;
  virtual std::uint32_t width() const = 0;
  virtual std::uint32_t height() const = 0;
  // Mono8 image into `pixels` (height rows of `stride` bytes). Must not allocate after the first call.
  virtual void render(const RenderRequest& req, std::span<std::uint8_t> pixels, std::uint32_t stride) = 0;
  // True sub-pixel stripe column per row for that mirror position; NaN where no stripe is visible.
  virtual void truth(double mirror_step, std::span<double> col_per_row) = 0;
};

}  // namespace fs::sim
