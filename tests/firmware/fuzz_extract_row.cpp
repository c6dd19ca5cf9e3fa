// Fuzz target: stripe extraction of arbitrary camera data (camera frames are external input). Byte 0 picks
// the sub-pixel method and the format (Mono8 / Mono16 / YUYV), byte 1 the row width; the rest is pixel data,
// extracted as a frame of whole rows. Must never crash; every point must lie inside its row and be finite,
// and every row must get exactly one status.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "firmware/extract/stripe_extractor.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const std::uint8_t sel = data[0];
  const std::uint32_t width = 1u + data[1] * 5u;  // 1 .. 1276 samples
  data += 2;
  size -= 2;
  fs::fw::ExtractParams p;
  p.method = static_cast<fs::fw::SubpixelMethod>(sel % 6);  // every method, gauss-log included
  const auto format = static_cast<fs::fw::PixelFormat>((sel / 6) % 3);
  const std::uint32_t bpp = format == fs::fw::PixelFormat::Mono8 ? 1 : 2;
  const std::uint32_t stride = width * bpp;
  const std::uint32_t height = static_cast<std::uint32_t>(size / stride);
  if (height == 0) return 0;
  std::vector<std::uint16_t> aligned((static_cast<std::size_t>(stride) * height + 1) /
                                     2);  // Mono16 alignment
  std::memcpy(aligned.data(), data, static_cast<std::size_t>(stride) * height);
  const fs::fw::FrameView f{
      reinterpret_cast<const std::uint8_t*>(aligned.data()), width, height, stride, format, 0, 0, 0};
  std::vector<fs::msg::StripePoint> out(height);
  const auto c = fs::fw::extract_frame(f, p, out);
  if (c.rows != height || c.points + c.no_stripe + c.ambiguous + c.saturated != height) __builtin_trap();
  for (std::uint32_t i = 0; i < c.points; ++i) {
    const auto& pt = out[i];
    if (pt.row >= height || !std::isfinite(pt.col) || pt.col < -0.5f ||
        pt.col > static_cast<float>(width) - 0.5f)
      __builtin_trap();
    if (!std::isfinite(pt.width) || pt.width < 0.0f) __builtin_trap();
  }
  return 0;
}
