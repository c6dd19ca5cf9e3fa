#include "hw-sim/scene/stripe_renderer.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

#include "common/error.hpp"
#include "hw-sim/scene/prng.hpp"

namespace fs::sim {
namespace {

constexpr std::size_t kNoiseTable = std::size_t{1} << 18;

}  // namespace

StripeRenderer::StripeRenderer(const Scene& scene, const RenderOptions& options)
    : scene_(&scene), options_(options), tracer_(scene) {
  const CameraModel& cam = scene.calibration.camera;
  truth_.resize(cam.height);
  peak_.resize(cam.height);
  sigma_.resize(cam.height);
  noise_.resize(kNoiseTable + cam.width);
  Prng rng(0x5EEDF00DULL);
  for (float& g : noise_) g = static_cast<float>(rng.gaussian());
  tile_.resize(std::size_t{kSpeckleTile} * kSpeckleTile);
  build_speckle_tile();
}

namespace {
double effective_grain(double g) { return g > 0.0 ? std::min(g, kMaxSpeckleGrainPx) : 0.0; }  // NaN: 0
}  // namespace

// White Gaussian noise filtered along both axes by the kernel whose periodic autocorrelation is the target
// r(d) = exp(-d^2 / (2 grain^2)) at every integer lag d (its spectrum the square root of r's, by a direct DFT
// of the tile's period; a sampled Gaussian blur would miss r at grains below ~1.5 px: 0.04 instead of 0.14 at
// lag 1 for 0.5 px), cut where it has fallen below 1e-4 of its peak, then scaled to unit variance over the
// tile. In place, one line of scratch on the stack. The separable field's correlation is r(dx) r(dy):
// isotropic.
void StripeRenderer::build_speckle_tile() {
  const double grain = effective_grain(options_.speckle_grain_px);
  tile_grain_ = grain;
  if (grain == 0.0) return;
  constexpr std::uint32_t T = kSpeckleTile, M = T - 1;
  static_assert(std::has_single_bit(T), "the tile's indices wrap by masks");
  constexpr int kMaxR = static_cast<int>(3.0 * kMaxSpeckleGrainPx) + 3;
  const int R = static_cast<int>(std::ceil(3.0 * grain)) + 2;  // <= kMaxR
  const int D = static_cast<int>(std::ceil(8.0 * grain)) + 1;  // r(D) < 1e-13
  const double two_pi_t = 2.0 * std::acos(-1.0) / T;
  float k[2 * kMaxR + 1];
  double spectrum[T / 2 + 1];  // symmetric: K(f) = K(T - f)
  for (std::uint32_t f = 0; f <= T / 2; ++f) {
    double p = 1.0;
    for (int d = 1; d <= D; ++d)
      p += 2.0 * std::exp(-0.5 * d * d / (grain * grain)) * std::cos(two_pi_t * f * d);
    spectrum[f] = std::sqrt(std::max(p, 0.0));
  }
  for (int n = -R; n <= R; ++n) {
    double a = spectrum[0] + spectrum[T / 2] * ((n & 1) ? -1.0 : 1.0);
    for (std::uint32_t f = 1; f < T / 2; ++f) a += 2.0 * spectrum[f] * std::cos(two_pi_t * f * n);
    k[n + R] = static_cast<float>(a / T);
  }
  Prng rng(0x5BEC1E5ULL);
  for (float& v : tile_) v = static_cast<float>(rng.gaussian());
  float line[T];
  const auto filter = [&](std::size_t first, std::size_t step) {  // one periodic line of the tile
    for (std::uint32_t x = 0; x < T; ++x) line[x] = tile_[first + x * step];
    for (std::uint32_t x = 0; x < T; ++x) {
      float a = 0.0f;
      for (int i = -R; i <= R; ++i)
        a += k[i + R] * line[(x + static_cast<std::uint32_t>(i + static_cast<int>(T))) & M];
      tile_[first + x * step] = a;
    }
  };
  for (std::uint32_t y = 0; y < T; ++y) filter(std::size_t{y} * T, 1);  // along the rows
  for (std::uint32_t x = 0; x < T; ++x) filter(x, T);                   // between the rows
  double sum = 0.0, sum2 = 0.0;
  for (const float v : tile_) {
    sum += v;
    sum2 += static_cast<double>(v) * v;
  }
  const double n = static_cast<double>(tile_.size()), mean = sum / n;
  const float inv = static_cast<float>(1.0 / std::sqrt(sum2 / n - mean * mean)), m = static_cast<float>(mean);
  for (float& v : tile_) v = (v - m) * inv;
}

void StripeRenderer::stripe_shape(const StripeSample& s, const Plane& laser, float& peak,
                                  float& sigma) const {
  const RenderOptions& o = options_;
  const CameraModel& cam = scene_->calibration.camera;
  const double sheet = o.sheet_sigma_mm + o.sheet_divergence * s.laser_distance;
  // The stripe runs along l (laser plane ∩ surface); across it, within the surface, is d. Moving along d by
  // a changes the distance to the laser plane by a * (n_L . d): the footprint is sheet / |n_L . d| wide.
  Vec3 l = laser.n.cross(s.normal);
  if (l.squaredNorm() < 1e-18) l = s.normal.unitOrthogonal();
  l.normalize();
  const Vec3 d = s.normal.cross(l).normalized();
  const double across = sheet / std::max(std::abs(laser.n.dot(d)), 0.05);
  Vec2 p0, p1, pt;
  double h = o.max_sigma_px;
  if (cam.project(s.point, p0) && cam.project(s.point + across * d, p1) && cam.project(s.point + l, pt)) {
    // Horizontal distance, along the image row, from the stripe's centre line to the band edge through p1.
    const Vec2 delta = p1 - p0;
    const Vec2 t = (pt - p0).normalized();
    if (std::abs(t.y()) > 1e-3) h = std::abs(delta.x() - delta.y() * t.x() / t.y());
  }
  const double sig = std::min(std::sqrt(h * h + o.min_sigma_px * o.min_sigma_px), o.max_sigma_px);
  const double r = o.reference_distance_mm / std::max(s.laser_distance, 1.0);
  sigma = static_cast<float>(sig);
  peak = static_cast<float>(o.laser_peak * std::max(s.cos_incidence, 0.0) * r * r);
}

template <typename Pixel>
void StripeRenderer::draw(const FrameBuffer& frame, std::uint64_t seed, double full_scale) {
  const RenderOptions& o = options_;
  const float scale = static_cast<float>(full_scale / 255.0);
  const float fs_max = static_cast<float>(full_scale);
  const float amb = static_cast<float>(o.ambient) * scale;
  const float read = static_cast<float>(o.sensor_noise * o.noise_scale) * scale;
  const float speckle = static_cast<float>(o.speckle * o.noise_scale);
  const float shot = static_cast<float>(o.shot_noise * o.noise_scale) * std::sqrt(scale);
  const std::uint32_t W = frame.width;
  const std::uint64_t span = kNoiseTable;  // offsets in [0, span): a row of W samples always fits
  Prng rng(seed);
  const bool grain = tile_grain_ > 0.0;
  constexpr std::uint32_t M = kSpeckleTile - 1;
  // The correlated pattern's offset in the tile, new for every kSpeckleTile rows (so that the periodic tile
  // never repeats within a frame), from a generator of its own (the rows' noise stays as it was).
  Prng tile_rng(seed ^ 0x7173A5EEDULL);
  std::uint32_t ox = 0, oy = 0;
  for (std::uint32_t r = 0; r < frame.height; ++r) {
    if (r % kSpeckleTile == 0) {
      ox = static_cast<std::uint32_t>(tile_rng.below(kSpeckleTile));
      oy = static_cast<std::uint32_t>(tile_rng.below(kSpeckleTile));
    }
    Pixel* out = reinterpret_cast<Pixel*>(frame.data + static_cast<std::size_t>(r) * frame.stride);
    const float* g = noise_.data() + rng.below(span);
    const float* g2 = noise_.data() + rng.below(span);
    const float* g3 = noise_.data() + rng.below(span);
    const float* trow = tile_.data() + static_cast<std::size_t>((r + oy) & M) * kSpeckleTile;
    for (std::uint32_t x = 0; x < W; ++x) {
      float v = amb + read * g[x];
      v = v < 0.0f ? 0.0f : (v > fs_max ? fs_max : v);
      out[x] = static_cast<Pixel>(v + 0.5f);
    }
    const StripeSample& s = truth_[r];
    if (!s.valid() || peak_[r] <= 0.0f) continue;
    const float u = static_cast<float>(s.column);
    const float sig = sigma_[r];
    const float pk = peak_[r] * scale;
    const bool ghost = o.spurious_reflection && s.object > 0;
    const float gu = u + static_cast<float>(o.reflection_offset_px);
    const float gsig = sig * static_cast<float>(o.reflection_width);
    const float gpk = pk * static_cast<float>(o.reflection_gain);
    float lo = u - 4.0f * sig, hi = u + 4.0f * sig;
    if (ghost) {
      lo = std::min(lo, gu - 4.0f * gsig);
      hi = std::max(hi, gu + 4.0f * gsig);
    }
    const int x0 = std::max(0, static_cast<int>(std::ceil(lo)));
    const int x1 = std::min(static_cast<int>(W) - 1, static_cast<int>(std::floor(hi)));
    const float inv2 = 0.5f / (sig * sig);
    const float ginv2 = 0.5f / (gsig * gsig);
    for (int x = x0; x <= x1; ++x) {
      const float dx = static_cast<float>(x) - u;
      float sgl = dx * dx * inv2 < 16.0f ? pk * std::exp(-dx * dx * inv2) : 0.0f;
      if (ghost) {
        const float gx = static_cast<float>(x) - gu;
        if (gx * gx * ginv2 < 16.0f) sgl += gpk * std::exp(-gx * gx * ginv2);
      }
      if (sgl <= 0.0f) continue;
      sgl *= 1.0f + speckle * (grain ? trow[(static_cast<std::uint32_t>(x) + ox) & M] : g2[x]);
      if (sgl > 0.0f) sgl += shot * std::sqrt(sgl) * g3[x];
      float v = amb + read * g[x] + sgl;
      v = v < 0.0f ? 0.0f : (v > fs_max ? fs_max : v);
      out[x] = static_cast<Pixel>(v + 0.5f);
    }
  }
}

void StripeRenderer::render(double mirror_angle_rad, std::uint64_t seed, const FrameBuffer& frame) {
  const CameraModel& cam = scene_->calibration.camera;
  if (frame.width != cam.width || frame.height != cam.height)
    throw Error("sim renderer: frame " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                " does not match the camera's " + std::to_string(cam.width) + "x" +
                std::to_string(cam.height));
  const std::uint32_t bpp = frame.format == FrameFormat::Mono16 ? 2 : 1;
  if (frame.data == nullptr || frame.stride < frame.width * bpp)
    throw Error("sim renderer: frame buffer missing or stride " + std::to_string(frame.stride) +
                " too small");
  if (bpp == 2 && (frame.stride % 2 != 0 || reinterpret_cast<std::uintptr_t>(frame.data) % 2 != 0))
    throw Error("sim renderer: Mono16 frames need 2-byte aligned rows (stride " +
                std::to_string(frame.stride) + ")");
  if (effective_grain(options_.speckle_grain_px) != tile_grain_) build_speckle_tile();
  laser_ = scene_->calibration.laser.plane_at_mirror_angle(mirror_angle_rad);
  tracer_.trace(laser_, truth_);
  for (std::size_t r = 0; r < truth_.size(); ++r) {
    peak_[r] = 0.0f;
    sigma_[r] = 0.0f;
    if (truth_[r].valid()) stripe_shape(truth_[r], laser_, peak_[r], sigma_[r]);
  }
  // The frame's noise depends on the seed and the angle only.
  std::uint64_t mix = seed ^ std::bit_cast<std::uint64_t>(mirror_angle_rad);
  const std::uint64_t frame_seed = splitmix64(mix);
  if (frame.format == FrameFormat::Mono16)
    draw<std::uint16_t>(frame, frame_seed, 65535.0);
  else
    draw<std::uint8_t>(frame, frame_seed, 255.0);
}

}  // namespace fs::sim
