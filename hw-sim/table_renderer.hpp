#pragma once
// The simplest physically correct stripe renderer: the laser plane on the bare table (no objects), through
// the calibrated camera model (with distortion). Per row the stripe centre is found by a secant search on
// the pixel column whose viewing ray hits the table on the laser plane; the profile is a pixel-integrated
// Gaussian over ambient light with additive Gaussian noise from a precomputed table (deterministic per seed).
#include <vector>

#include "common/calibration.hpp"
#include "hw-sim/frame_renderer.hpp"

namespace fs::sim {

struct TableRenderParams {
  double ambient = 20.0;     // DN
  double amplitude = 170.0;  // peak above ambient at full laser power, DN
  double sigma_px = 1.6;     // stripe profile sigma
  double noise = 2.0;        // sensor noise sigma, DN
};

class TableStripeRenderer final : public FrameRenderer {
 public:
  explicit TableStripeRenderer(const ScannerCalibration& cal, TableRenderParams params = {});
  std::uint32_t width() const override { return cal_.camera.width; }
  std::uint32_t height() const override { return cal_.camera.height; }
  void render(const RenderRequest& req, std::span<std::uint8_t> pixels, std::uint32_t stride) override;
  void truth(double mirror_step, std::span<double> col_per_row) override;

 private:
  ScannerCalibration cal_;
  TableRenderParams p_;
  std::vector<double> cols_;
  std::vector<std::uint8_t> background_;  // ambient + noise, 2x the frame so any offset is a valid window
  std::vector<float> noise_;              // N(0, noise) samples
};

}  // namespace fs::sim
