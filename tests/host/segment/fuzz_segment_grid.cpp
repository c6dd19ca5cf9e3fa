// Fuzz target: arbitrary organized grids (sizes, coordinates incl. NaN / inf / huge values, viewpoint)
// through segmentation and scene-PFRG building. Must never crash, hang or trip the sanitizers.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "common/error.hpp"
#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segmenter.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 3) return 0;
  const std::uint32_t w = 1 + data[0] % 48, h = 1 + data[1] % 48;
  fs::host::seg::SegmentParams params =
      (data[2] & 1) ? fs::host::seg::SegmentParams::kinect() : fs::host::seg::SegmentParams::laser();
  params.min_region_cells = 4;
  params.min_grow_cells = 3;
  params.min_region_area_mm2 = 0.0;
  data += 3;
  size -= 3;
  fs::host::OrganizedCloud cloud;
  cloud.reset(w, h);
  // Values: pairs of bytes -> a depth on a coarse lattice (so that planes occur), 0xFFFF -> NaN,
  // 0xFFFE -> raw float bits from the next 4 bytes.
  std::size_t k = 0;
  for (std::size_t i = 0; i < cloud.points.size() && k + 2 <= size; ++i) {
    const std::uint16_t v = std::uint16_t(data[k] | (data[k + 1] << 8));
    k += 2;
    const float x = float(i % w), y = float(i / w);
    if (v == 0xFFFF) continue;
    float z = float(v % 512) * 0.25f;
    if (v == 0xFFFE && k + 4 <= size) {
      std::memcpy(&z, data + k, 4);
      k += 4;
    }
    cloud.points[i] = Eigen::Vector3f(x, y, z);
  }
  cloud.viewpoint = Eigen::Vector3d(w / 2.0, h / 2.0, 300.0);
  fs::host::seg::SegmentLimits limits;
  limits.max_cells = 48 * 48;
  limits.max_regions = 1 + (size % 64);
  limits.max_borders = 1 + (size % 128);
  fs::host::seg::Segmenter seg(params, limits);
  fs::host::seg::Segmentation s;
  seg.segment(cloud, s);
  fs::host::seg::ScenePfrgBuilder b(limits.max_regions, limits.max_borders);
  fs::host::Pfrg g;
  b.build(s, g);
  return 0;
}
