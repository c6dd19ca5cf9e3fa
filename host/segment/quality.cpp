#include "host/segment/quality.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace fs::host::seg {

const char* to_string(HooverClass c) {
  switch (c) {
    case HooverClass::Correct:
      return "correct";
    case HooverClass::Over:
      return "over";
    case HooverClass::Under:
      return "under";
    case HooverClass::Missed:
      return "missed";
    case HooverClass::Noise:
      return "noise";
  }
  return "?";
}

HooverResult hoover_compare(std::span<const std::int32_t> gt, const Segmentation& seg, double T,
                            const std::function<std::optional<Vec3>(std::int32_t)>& gt_normal) {
  HooverResult res;
  const std::size_t n = std::min(gt.size(), seg.labels.size());
  std::map<std::int32_t, double> gsize;                      // |G|
  std::map<std::int32_t, double> msize;                      // |M|
  std::map<std::int32_t, std::map<std::int32_t, double>> O;  // O[g][m]
  auto machine = [&](std::int32_t l) {
    return l >= 0 && std::size_t(l) < seg.regions.size() && seg.regions[std::size_t(l)].known ? l : -1;
  };
  for (std::size_t i = 0; i < n; ++i) {
    const std::int32_t g = gt[i], m = machine(seg.labels[i]);
    if (g >= 0) gsize[g] += 1;
    if (m >= 0) msize[m] += 1;
    if (g >= 0 && m >= 0) O[g][m] += 1;
  }
  res.gt_regions = int(gsize.size());
  res.machine_regions = int(msize.size());
  std::map<std::int32_t, std::map<std::int32_t, double>> OT;  // transposed: OT[m][g]
  for (const auto& [g, row] : O)
    for (const auto& [m, o] : row) OT[m][g] = o;
  std::map<std::int32_t, bool> gused, mused;

  // Correct detections.
  for (const auto& [g, row] : O) {
    for (const auto& [m, o] : row) {
      if (o >= T * gsize[g] && o >= T * msize[m] && !gused[g] && !mused[m]) {
        HooverMapping mp;
        mp.cls = HooverClass::Correct;
        mp.gt = {g};
        mp.machine = {m};
        if (gt_normal) {
          if (auto tn = gt_normal(g)) {
            const double c =
                std::min(1.0, std::abs(tn->normalized().dot(seg.regions[std::size_t(m)].plane.n)));
            mp.angle_error_deg = std::acos(c) * 180.0 / 3.14159265358979323846;
          }
        }
        gused[g] = mused[m] = true;
        res.gt_correct_region[g] = m;
        res.mappings.push_back(mp);
      }
    }
  }
  // Over-segmentation: one G, several M each mostly inside G, together covering >= T of G.
  for (const auto& [g, row] : O) {
    if (gused[g]) continue;
    std::vector<std::int32_t> ms;
    double sum_o = 0, sum_m = 0;
    for (const auto& [m, o] : row) {
      if (!mused[m] && o >= T * msize[m]) {
        ms.push_back(m);
        sum_o += o;
        sum_m += msize[m];
      }
    }
    if (ms.size() >= 2 && sum_o >= T * gsize[g] && sum_o >= T * sum_m) {
      HooverMapping mp;
      mp.cls = HooverClass::Over;
      mp.gt = {g};
      mp.machine = ms;
      gused[g] = true;
      for (auto m : ms) mused[m] = true;
      res.mappings.push_back(mp);
    }
  }
  // Under-segmentation: one M, several G each mostly inside M.
  for (const auto& [m, col] : OT) {
    if (mused[m]) continue;
    std::vector<std::int32_t> gs;
    double sum_o = 0, sum_g = 0;
    for (const auto& [g, o] : col) {
      if (!gused[g] && o >= T * gsize[g]) {
        gs.push_back(g);
        sum_o += o;
        sum_g += gsize[g];
      }
    }
    if (gs.size() >= 2 && sum_o >= T * msize[m] && sum_o >= T * sum_g) {
      HooverMapping mp;
      mp.cls = HooverClass::Under;
      mp.gt = gs;
      mp.machine = {m};
      mused[m] = true;
      for (auto g : gs) gused[g] = true;
      res.mappings.push_back(mp);
    }
  }
  for (const auto& mp : res.mappings) {
    switch (mp.cls) {
      case HooverClass::Correct:
        ++res.correct;
        break;
      case HooverClass::Over:
        ++res.over;
        break;
      case HooverClass::Under:
        ++res.under;
        break;
      default:
        break;
    }
    for (auto g : mp.gt) res.gt_class[g] = mp.cls;
  }
  for (const auto& [g, s] : gsize) {
    if (!gused[g]) {
      ++res.missed;
      res.gt_class[g] = HooverClass::Missed;
    }
  }
  for (const auto& [m, s] : msize) res.noise += mused[m] ? 0 : 1;
  int na = 0;
  for (const auto& mp : res.mappings) {
    if (mp.angle_error_deg < 0) continue;
    res.mean_angle_error_deg += mp.angle_error_deg;
    res.max_angle_error_deg = std::max(res.max_angle_error_deg, mp.angle_error_deg);
    ++na;
  }
  if (na > 0) res.mean_angle_error_deg /= na;
  return res;
}

ObjectSpan object_span(std::span<const std::int32_t> object, const Segmentation& seg, double purity) {
  ObjectSpan res;
  const std::size_t n = std::min(object.size(), seg.labels.size());
  std::vector<std::unordered_map<std::int32_t, std::uint32_t>> count(seg.regions.size());
  for (std::size_t i = 0; i < n; ++i) {
    const std::int32_t l = seg.labels[i];
    if (l < 0 || !seg.regions[std::size_t(l)].known || object[i] < 0) continue;
    ++count[std::size_t(l)][object[i]];
  }
  for (std::size_t r = 0; r < seg.regions.size(); ++r) {
    if (count[r].empty()) continue;
    std::uint32_t total = 0, best = 0;
    for (const auto& [o, c] : count[r]) {
      total += c;
      best = std::max(best, c);
    }
    const double area = seg.regions[r].area;
    res.total_area += area;
    ++res.regions;
    if (double(best) >= purity * double(total)) {
      res.pure_area += area;
      ++res.pure_regions;
    }
  }
  return res;
}

}  // namespace fs::host::seg
