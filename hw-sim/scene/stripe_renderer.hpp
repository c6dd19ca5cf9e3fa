#pragma once
// Renders the camera frame of a laser-stripe scanner for one mirror angle: ambient light with sensor noise
// over the whole frame (precomputed Gaussian noise table read at random row offsets: cheap), and, per image
// row, the stripe as a Gaussian profile centred exactly on the ground-truth column (stripe_truth.hpp) whose
// width grows with the laser sheet's thickness at that distance and with the incidence angle, and whose peak
// falls with distance squared and with the cosine of incidence; speckle (multiplicative) and shot noise on
// the stripe, saturation at full scale, and optionally a spurious reflection (a weaker, wider ghost stripe
// next to the real one where the laser hits an object). Only the pixels near the stripe are computed per row.
//
// All buffers are allocated in the constructor; render() does not allocate. Deterministic for (angle, seed).
#include <cstdint>
#include <span>
#include <vector>

#include "hw-sim/scene/stripe_tracer.hpp"

namespace fs::sim {

enum class FrameFormat : std::uint8_t { Mono8 = 0, Mono16 = 1 };

// A caller-owned image: `stride` bytes per row, Mono16 samples native-endian.
struct FrameBuffer {
  std::uint8_t* data = nullptr;
  std::uint32_t width = 0, height = 0;
  std::uint32_t stride = 0;
  FrameFormat format = FrameFormat::Mono8;
};

// Light levels are in 8-bit digital numbers (DN); Mono16 frames are scaled by 257 (full scale 65535).
struct RenderOptions {
  double ambient = 14.0;      // background level
  double laser_peak = 210.0;  // stripe peak on a surface facing the mirror at reference_distance_mm
  double reference_distance_mm = 500.0;
  double sheet_sigma_mm = 0.35;      // laser sheet half-thickness (Gaussian sigma) at the waist
  double sheet_divergence = 0.0006;  // sigma growth, mm per mm of distance from the mirror
  double min_sigma_px = 0.7;         // optics blur: the stripe is never narrower than this (sigma, px)
  double max_sigma_px = 12.0;        // grazing incidence: cap on the width
  double sensor_noise = 1.5;         // read noise sigma, DN (whole frame)
  double shot_noise = 0.35;          // shot noise sigma = shot_noise * sqrt(signal), DN
  double speckle = 0.12;             // relative sigma of the multiplicative speckle on stripe pixels
  // Speckle grain: the correlation length (px) of the speckle pattern, along the row and between rows (its
  // correlation at a distance of d pixels is exp(-d^2 / (2 grain^2))). 0 = independent per pixel (the
  // default, and the numbers of docs/performance.md unless they name a grain); a real laser's subjective
  // speckle is about a pixel or more
  // (~1.2 lambda F# (1 + M) on the sensor), correlated in both directions. Kept at most kMaxSpeckleGrainPx.
  double speckle_grain_px = 0.0;
  double noise_scale = 1.0;  // multiplies sensor_noise, shot_noise and speckle (0 = noise-free)
  bool spurious_reflection = false;
  double reflection_gain = 0.35;       // ghost peak relative to the stripe's
  double reflection_offset_px = 18.0;  // ghost column = true column + offset (toward larger u)
  double reflection_width = 2.5;       // ghost sigma relative to the stripe's
};

constexpr double kMaxSpeckleGrainPx = 8.0;

class StripeRenderer {
 public:
  StripeRenderer(const Scene& scene, const RenderOptions& options = {});

  // Renders the frame for a mirror angle (rad). frame.width/height must equal the camera's; frame.stride must
  // hold a row. Throws fs::Error on a mismatched buffer. The ground truth of the frame is truth() afterwards.
  void render(double mirror_angle_rad, std::uint64_t seed, const FrameBuffer& frame);
  void render_step(double step, std::uint64_t seed, const FrameBuffer& frame) {
    render(scene_->calibration.laser.mirror_angle(step), seed, frame);
  }

  // Per image row of the last frame: true centre, 3D point, object id, face id (stripe_truth.hpp).
  std::span<const StripeSample> truth() const { return truth_; }
  // The correlated speckle pattern (speckle_grain_px > 0): a periodic kSpeckleTile x kSpeckleTile field of
  // unit variance, read at a random offset per frame and per kSpeckleTile rows (row r, column x: tile row (r
  // + oy) mod kSpeckleTile, column (x + ox) mod kSpeckleTile). Built at construction and again by the first
  // render after the grain changed, in place (no allocation; it filters the 512^2 samples along both axes: a
  // pause, much longer under emulation). Exposed for tests of its statistics.
  static constexpr std::uint32_t kSpeckleTile = 512;
  std::span<const float> speckle_tile() const { return tile_; }

  // Peak value (DN) and sigma (px) of the stripe drawn in each row of the last frame (0 where none).
  std::span<const float> peak() const { return peak_; }
  std::span<const float> sigma_px() const { return sigma_; }

  RenderOptions& options() { return options_; }
  const Scene& scene() const { return *scene_; }

 private:
  void stripe_shape(const StripeSample& s, const Plane& laser, float& peak, float& sigma) const;
  template <typename Pixel>
  void draw(const FrameBuffer& frame, std::uint64_t seed, double full_scale);

  const Scene* scene_;
  RenderOptions options_;
  StripeTracer tracer_;
  std::vector<StripeSample> truth_;
  std::vector<float> peak_, sigma_;
  std::vector<float> noise_;  // standard normal samples, read at random offsets
  void build_speckle_tile();
  std::vector<float> tile_;  // the correlated speckle pattern, kSpeckleTile^2
  double tile_grain_ = 0.0;  // the grain tile_ was built for (0: not built)
  Plane laser_;
};

}  // namespace fs::sim
