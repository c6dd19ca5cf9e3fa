#include "common/png_write.hpp"

#include <png.h>

#include <cstdio>
#include <memory>
#include <vector>

#include "common/error.hpp"

namespace fs {

namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

// Writes rows given by row(i) -> pointer; bit_depth 8 or 16; color PNG_COLOR_TYPE_GRAY or _RGB.
template <typename RowFn>
void write_png(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height, int bit_depth,
               int color_type, RowFn row) {
  if (width == 0 || height == 0) throw Error(path.string() + ": cannot write an empty image");
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "wb"));
  if (!f) throw Error(path.string() + ": cannot open for writing");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    throw Error(path.string() + ": libpng initialisation failed");
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw Error(path.string() + ": libpng write error");
  }
  png_init_io(png, f.get());
  png_set_IHDR(png, info, width, height, bit_depth, color_type, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  if (bit_depth == 16) png_set_swap(png);  // PNG is big-endian; our samples are little-endian
  for (std::uint32_t y = 0; y < height; ++y) png_write_row(png, row(y));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
}

void check_size(const std::filesystem::path& path, std::size_t have, std::size_t need) {
  if (have < need)
    throw Error(path.string() + ": image buffer holds " + std::to_string(have) + " samples, needs " +
                std::to_string(need));
}

}  // namespace

void write_png_gray8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                     std::span<const std::uint8_t> pixels, std::uint32_t stride) {
  if (height > 0) check_size(path, pixels.size(), std::size_t(stride) * (height - 1) + width);
  write_png(path, width, height, 8, PNG_COLOR_TYPE_GRAY,
            [&](std::uint32_t y) { return const_cast<png_bytep>(pixels.data() + std::size_t(y) * stride); });
}

void write_png_gray16(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                      std::span<const std::uint16_t> pixels, std::uint32_t stride) {
  if (height > 0) check_size(path, pixels.size(), std::size_t(stride) * (height - 1) + width);
  write_png(path, width, height, 16, PNG_COLOR_TYPE_GRAY, [&](std::uint32_t y) {
    return reinterpret_cast<png_bytep>(const_cast<std::uint16_t*>(pixels.data() + std::size_t(y) * stride));
  });
}

void write_png_rgb8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                    std::span<const std::uint8_t> rgb) {
  check_size(path, rgb.size(), std::size_t(width) * height * 3);
  write_png(path, width, height, 8, PNG_COLOR_TYPE_RGB,
            [&](std::uint32_t y) { return const_cast<png_bytep>(rgb.data() + std::size_t(y) * width * 3); });
}

}  // namespace fs
