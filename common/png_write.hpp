#pragma once
// PNG output (libpng) for pictures people look at: stripe frames, segmentation images.
#include <cstdint>
#include <filesystem>
#include <span>

namespace fs {

// 8-bit grayscale, rows of `stride` bytes (>= width).
void write_png_gray8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                     std::span<const std::uint8_t> pixels, std::uint32_t stride);
// 16-bit grayscale, native-endian samples, rows of `stride` samples.
void write_png_gray16(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                      std::span<const std::uint16_t> pixels, std::uint32_t stride);
// 8-bit RGB, tightly packed rows (3 * width bytes).
void write_png_rgb8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                    std::span<const std::uint8_t> rgb);

}  // namespace fs
