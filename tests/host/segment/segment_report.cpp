// segment_report: the quality numbers of docs/performance.md.
//   segment_report hwsim [NOISE_MM]         Hoover classes / normal errors / PFRG check on the hw-sim scenes
//   segment_report mosd [FILES...]           object-span purity on mOSD (default: all 24 test scenes)
//   segment_report faces SCENE [NOISE_MM]   per ground-truth face of an hw-sim scene: the regions covering it
//                                           (cells, share), per region its faces: which faces merge, and why
#include <cstdio>
#include <ctime>
#include <map>
#include <string>
#include <vector>

#include "host/io/load.hpp"
#include "hwsim_eval.hpp"
#include "support/test_paths.hpp"
#include "support/thread_cpu.hpp"

using namespace fs::host;

namespace {

int hwsim(double noise) {
  std::printf(
      "| scene | GT faces (>2%%) | correct | over | under | missed | noise | max normal err (deg) | mean "
      "normal err (deg) | PFRG nodes | arcs known-known (expected) | ok |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (const char* name :
       {"pyramid", "cube", "cube-occludes-pyramid", "cube-pyramid-separate", "corner", "default"}) {
    const auto path = fs::test::source_dir() / "hw-sim/scenes" / (std::string(name) + ".json");
    if (!std::filesystem::exists(path)) continue;
    const auto ev = fs::test::evaluate_hwsim_scene(path, noise);
    const bool ok = ev.problems.empty() && ev.max_normal_error_deg < 1.0 &&
                    ev.graph.nodes.size() == ev.significant.size() + 1 && ev.actual_arcs == ev.expected_arcs;
    std::printf("| %s | %zu | %d | %d | %d | %d | %d | %.3f | %.3f | %zu | %zu (%zu) | %s |\n", name,
                ev.significant.size(), ev.significant_correct, ev.hoover.over, ev.hoover.under,
                ev.hoover.missed, ev.hoover.noise, ev.max_normal_error_deg, ev.hoover.mean_angle_error_deg,
                ev.graph.nodes.size(), ev.actual_arcs.size(), ev.expected_arcs.size(), ok ? "yes" : "NO");
    for (const auto& p : ev.problems) std::printf("  - %s\n", p.c_str());
  }
  return 0;
}

int mosd(std::vector<std::string> files) {
  if (files.empty())
    for (int k = 0; k < 24; ++k)
      files.push_back(
          (fs::test::shared_data() / "mosd-boxes/test" / ("test" + std::to_string(k) + ".pcd")).string());
  std::printf(
      "| file | known regions | pure regions | pure area share | PFRG nodes | arcs | ms CPU |\n| --- | --- | "
      "--- | --- | --- | --- | --- |\n");
  double tot = 0, pure = 0;
  int worst_file = -1;
  double worst = 2;
  // set up once, as the recognizer does (no allocation per scan); ms = this thread's CPU time per scan
  seg::Segmenter segmenter(seg::SegmentParams::kinect());
  seg::ScenePfrgBuilder builder;
  seg::Segmentation s;
  Pfrg g;
  segmenter.prepare(s);
  builder.prepare(g);
  auto cpu_ms = [] { return fs::test::thread_cpu_seconds() * 1e3; };
  for (std::size_t f = 0; f < files.size(); ++f) {
    OrganizedCloud cloud;
    load_cloud(files[f], cloud);
    const double t0 = cpu_ms();
    segmenter.segment(cloud, s);
    builder.build(s, g);
    const double ms = cpu_ms() - t0;
    std::vector<std::int32_t> obj(cloud.labels.size());
    for (std::size_t i = 0; i < obj.size(); ++i) obj[i] = seg::mosd_object(cloud.labels[i]);
    const auto sp = seg::object_span(obj, s);
    tot += sp.total_area;
    pure += sp.pure_area;
    if (sp.pure_fraction() < worst) {
      worst = sp.pure_fraction();
      worst_file = int(f);
    }
    std::printf("| %s | %d | %d | %.4f | %zu | %zu | %.1f |\n",
                std::filesystem::path(files[f]).filename().c_str(), sp.regions, sp.pure_regions,
                sp.pure_fraction(), g.nodes.size(), g.arcs.size(), ms);
  }
  std::printf("\nall files: pure area share %.4f; worst %s %.4f\n", tot > 0 ? pure / tot : 1.0,
              worst_file >= 0 ? files[std::size_t(worst_file)].c_str() : "-", worst);
  return 0;
}

// Which ground-truth faces share a region (and which regions share a face) in one hw-sim scene.
int faces(const std::string& name, double noise) {
  auto path = fs::test::source_dir() / "hw-sim/scenes" / (name + ".json");
  if (!std::filesystem::exists(path)) path = name;
  const auto ev = fs::test::evaluate_hwsim_scene(path, noise);
  const auto& L = ev.cloud.labels;
  std::map<std::int32_t, std::map<std::int32_t, int>> by_face, by_region;  // gt -> region -> cells, and back
  for (std::size_t i = 0; i < L.size(); ++i) {
    const std::int32_t r = ev.seg.labels[i];
    const std::int32_t key = r < 0 ? -1 : (ev.seg.regions[std::size_t(r)].known ? r : -2);
    ++by_face[L[i]][key];
    ++by_region[key][L[i]];
  }
  std::printf("ground-truth face -> regions (cells; -1 = no data / NIL, -2 = unknown regions)\n");
  for (const auto& [f, m] : by_face) {
    const auto a = ev.face_area.find(f);
    std::printf("  face %6d (%7.1f mm^2%s):", f, a == ev.face_area.end() ? 0.0 : a->second,
                ev.significant.count(f) ? ", >2%" : "");
    for (const auto& [r, n] : m) std::printf(" r%d:%d", r, n);
    std::printf("\n");
  }
  std::printf("known region -> ground-truth faces (cells), plane n, d\n");
  for (const auto& [r, m] : by_region) {
    if (r < 0) continue;
    const auto& g = ev.seg.regions[std::size_t(r)];
    std::printf("  r%-4d n=(%.3f %.3f %.3f) d=%.2f area %.1f:", r, g.plane.n.x(), g.plane.n.y(),
                g.plane.n.z(), g.plane.d, g.area);
    for (const auto& [f, n] : m) std::printf(" %d:%d", f, n);
    std::printf("\n");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string mode = argc > 1 ? argv[1] : "hwsim";
    if (mode == "hwsim") return hwsim(argc > 2 ? std::stod(argv[2]) : 0.05);
    if (mode == "faces" && argc > 2) return faces(argv[2], argc > 3 ? std::stod(argv[3]) : 0.05);
    if (mode == "mosd") return mosd(std::vector<std::string>(argv + 2, argv + argc));
    std::fprintf(stderr,
                 "usage: segment_report hwsim [NOISE_MM] | mosd [FILES...] | faces SCENE [NOISE_MM]\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "segment_report: %s\n", e.what());
    return 1;
  }
}
