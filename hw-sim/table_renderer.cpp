#include "hw-sim/table_renderer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace fs::sim {

TableStripeRenderer::TableStripeRenderer(const ScannerCalibration& cal, TableRenderParams params)
    : cal_(cal), p_(params), cols_(cal.camera.height) {
  std::mt19937_64 rng(12345);
  std::normal_distribution<float> nd(0.0f, static_cast<float>(p_.noise));
  const std::size_t n = static_cast<std::size_t>(cal_.camera.width) * cal_.camera.height;
  background_.resize(2 * n);
  for (auto& b : background_)
    b = static_cast<std::uint8_t>(std::clamp(std::lround(p_.ambient + nd(rng)), 0L, 255L));
  noise_.resize(1 << 16);
  for (auto& v : noise_) v = nd(rng);
}

void TableStripeRenderer::truth(double mirror_step, std::span<double> out) {
  const CameraModel& cam = cal_.camera;
  const Plane laser = cal_.laser.plane_at_step(mirror_step);
  const Vec3 o = cam.center();
  // g(u) = signed distance of the table hit of pixel (u, v) from the laser plane; root in u.
  for (std::uint32_t v = 0; v < cam.height && v < out.size(); ++v) {
    auto g = [&](double u, bool& ok) {
      Vec3 hit;
      ok = intersect_ray_plane(o, cam.ray_world(Vec2(u, v)), cal_.table, 1e-6, hit);
      return ok ? laser.signed_distance(hit) : 0.0;
    };
    bool ok0 = false, ok1 = false;
    double u0 = 0.0, u1 = cam.width - 1.0;
    double g0 = g(u0, ok0), g1 = g(u1, ok1);
    double col = std::numeric_limits<double>::quiet_NaN();
    if (ok0 && ok1 && (g0 < 0) != (g1 < 0)) {
      for (int it = 0; it < 60; ++it) {  // regula falsi (Illinois), converges in a few iterations
        const double u = u1 - g1 * (u1 - u0) / (g1 - g0);
        bool ok = false;
        const double gu = g(u, ok);
        if (!ok) break;
        if (std::abs(gu) < 1e-9 || std::abs(u1 - u0) < 1e-9) {
          col = u;
          break;
        }
        if ((gu < 0) == (g1 < 0)) {
          u1 = u;
          g1 = gu;
          g0 *= 0.5;
        } else {
          u0 = u1;
          g0 = g1;
          u1 = u;
          g1 = gu;
        }
        col = u;
      }
    }
    out[v] = col;
  }
}

void TableStripeRenderer::render(const RenderRequest& req, std::span<std::uint8_t> pixels,
                                 std::uint32_t stride) {
  const std::uint32_t w = width(), h = height();
  const std::size_t n = static_cast<std::size_t>(w) * h;
  const std::size_t offset = static_cast<std::size_t>((req.seed * 2654435761ull) % n);
  const double amp = p_.amplitude * std::clamp(req.laser_fraction, 0.0, 1.0) * req.gain;
  if (amp > 0.0) truth(req.mirror_step, cols_);
  const double s = p_.sigma_px * std::sqrt(2.0);
  std::size_t noise_i = static_cast<std::size_t>(req.seed * 40503u);
  for (std::uint32_t v = 0; v < h; ++v) {
    std::uint8_t* row = pixels.data() + static_cast<std::size_t>(v) * stride;
    std::copy_n(background_.data() + offset + static_cast<std::size_t>(v) * w, w, row);
    const double c = cols_[v];
    if (!std::isfinite(c) || amp <= 0.0) continue;
    const int lo = std::max(0, static_cast<int>(std::floor(c - 6.0 * p_.sigma_px)));
    const int hi = std::min(static_cast<int>(w) - 1, static_cast<int>(std::ceil(c + 6.0 * p_.sigma_px)));
    for (int u = lo; u <= hi; ++u) {
      // Pixel-integrated Gaussian with unit peak density.
      const double e = 0.5 * (std::erf((u + 0.5 - c) / s) - std::erf((u - 0.5 - c) / s)) * p_.sigma_px *
                       std::sqrt(2.0 * M_PI);
      const double val = p_.ambient + amp * e + noise_[noise_i++ & (noise_.size() - 1)];
      row[u] = static_cast<std::uint8_t>(std::clamp(std::lround(val), 0L, 255L));
    }
  }
}

}  // namespace fs::sim
