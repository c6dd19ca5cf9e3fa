// fs_fscan_compare: compares two .fscan recordings of the same simulated scan (e.g. native x86-64 vs. the
// aarch64 cross build under qemu-user). Both files are decoded with common/scan_file.hpp.
//
//   fs_fscan_compare REFERENCE.fscan OTHER.fscan [--col-tol PX] [--width-tol PX] [--peak-tol N]
//
// Required equal: number of stripes, per stripe its step index and number of points, per point its row, the
// ScanEnd counters (stripes sent, frames captured/dropped, completed). Compared within a tolerance (libm and
// FMA contraction differ across architectures): sub-pixel column (default 0.01 px), stripe width
// (default 0.05 px), peak intensity (default 2 counts). Exit 0 = equivalent, 1 = different, 2 = bad input.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "common/error.hpp"
#include "common/scan_file.hpp"

namespace {

struct PointRec {
  std::uint16_t row;
  float col;
  std::uint16_t peak;
  float width;
};
struct StripeRec {
  std::uint32_t step;
  std::vector<PointRec> points;
};
struct Scan {
  std::vector<StripeRec> stripes;
  bool has_end = false;
  fs::msg::ScanEnd end;
  std::size_t points = 0;
};

Scan load(const std::string& path) {
  Scan s;
  fs::ScanFileReader reader(std::filesystem::path{path});
  fs::wire::DecodedMessage m;
  while (reader.next(m)) {
    if (m.type == fs::msg::Type::Stripe) {
      StripeRec r{m.stripe.header.step_index, {}};
      r.points.reserve(m.stripe.points.size());
      for (const auto& p : m.stripe.points) r.points.push_back({p.row, p.col, p.peak, p.width});
      s.points += r.points.size();
      s.stripes.push_back(std::move(r));
    } else if (m.type == fs::msg::Type::ScanEnd) {
      s.has_end = true;
      s.end = m.scan_end;
    }
  }
  return s;
}

double parse_tol(const char* flag, const char* v) {
  char* end = nullptr;
  const double d = std::strtod(v, &end);
  if (end == v || *end != '\0' || !(d >= 0.0)) {
    std::fprintf(stderr, "fs_fscan_compare: %s: '%s' is not a non-negative number\n", flag, v);
    std::exit(2);
  }
  return d;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> files;
  double col_tol = 0.01, width_tol = 0.05, peak_tol = 2.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--col-tol" || a == "--width-tol" || a == "--peak-tol") && i + 1 < argc) {
      const double v = parse_tol(argv[i], argv[i + 1]);
      ++i;
      (a == "--col-tol" ? col_tol : a == "--width-tol" ? width_tol : peak_tol) = v;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "fs_fscan_compare: unknown option '%s'\n", a.c_str());
      return 2;
    } else {
      files.push_back(a);
    }
  }
  if (files.size() != 2) {
    std::fprintf(stderr,
                 "usage: fs_fscan_compare REFERENCE.fscan OTHER.fscan [--col-tol PX] [--width-tol PX] "
                 "[--peak-tol N]\n");
    return 2;
  }
  Scan a, b;
  try {
    a = load(files[0]);
    b = load(files[1]);
  } catch (const fs::Error& e) {
    std::fprintf(stderr, "fs_fscan_compare: %s\n", e.what());
    return 2;
  }
  int problems = 0;
  auto fail = [&](const std::string& what) {
    if (++problems <= 20) std::fprintf(stderr, "DIFF: %s\n", what.c_str());
  };
  std::printf("%s: %zu stripes, %zu points\n%s: %zu stripes, %zu points\n", files[0].c_str(),
              a.stripes.size(), a.points, files[1].c_str(), b.stripes.size(), b.points);
  if (a.stripes.empty()) fail("the reference scan has no stripes");
  if (a.stripes.size() != b.stripes.size())
    fail("stripe count " + std::to_string(a.stripes.size()) + " vs " + std::to_string(b.stripes.size()));
  if (a.points != b.points)
    fail("point count " + std::to_string(a.points) + " vs " + std::to_string(b.points));
  if (a.has_end != b.has_end) fail("only one file has a ScanEnd message");
  if (a.has_end && b.has_end) {
    if (a.end.stripes_sent != b.end.stripes_sent) fail("ScanEnd.stripes_sent differs");
    if (a.end.frames_captured != b.end.frames_captured) fail("ScanEnd.frames_captured differs");
    if (a.end.frames_dropped != b.end.frames_dropped) fail("ScanEnd.frames_dropped differs");
    if (a.end.completed != b.end.completed) fail("ScanEnd.completed differs");
  }
  double max_col = 0.0, max_width = 0.0, max_peak = 0.0;
  const std::size_t n = std::min(a.stripes.size(), b.stripes.size());
  for (std::size_t i = 0; i < n; ++i) {
    const auto& sa = a.stripes[i];
    const auto& sb = b.stripes[i];
    const std::string where = "stripe " + std::to_string(i) + " (step " + std::to_string(sa.step) + ")";
    if (sa.step != sb.step) fail(where + ": step index " + std::to_string(sb.step) + " in the other file");
    if (sa.points.size() != sb.points.size()) {
      fail(where + ": " + std::to_string(sa.points.size()) + " vs " + std::to_string(sb.points.size()) +
           " points");
      continue;
    }
    for (std::size_t j = 0; j < sa.points.size(); ++j) {
      const auto& pa = sa.points[j];
      const auto& pb = sb.points[j];
      if (pa.row != pb.row) fail(where + ": point " + std::to_string(j) + " row differs");
      const double dc = std::fabs(double(pa.col) - double(pb.col));
      const double dw = std::fabs(double(pa.width) - double(pb.width));
      const double dp = std::fabs(double(pa.peak) - double(pb.peak));
      max_col = std::max(max_col, dc);
      max_width = std::max(max_width, dw);
      max_peak = std::max(max_peak, dp);
      if (!(dc <= col_tol))
        fail(where + " row " + std::to_string(pa.row) + ": column differs by " + std::to_string(dc));
      if (!(dw <= width_tol))
        fail(where + " row " + std::to_string(pa.row) + ": width differs by " + std::to_string(dw));
      if (!(dp <= peak_tol))
        fail(where + " row " + std::to_string(pa.row) + ": peak differs by " + std::to_string(dp));
    }
  }
  std::printf(
      "max |d col| = %.6g px (tol %g), max |d width| = %.6g px (tol %g), max |d peak| = %g (tol %g)\n",
      max_col, col_tol, max_width, width_tol, max_peak, peak_tol);
  if (problems) {
    std::printf("DIFFERENT: %d difference(s)\n", problems);
    return 1;
  }
  std::printf("EQUIVALENT\n");
  return 0;
}
