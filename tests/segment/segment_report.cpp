// segment_report: the quality numbers of docs/readme/segment.md.
//   segment_report hwsim [NOISE_MM]         Hoover classes / normal errors / PFRG check on the hw-sim scenes
//   segment_report mosd [FILES...]           object-span purity on mOSD (default: all 24 test scenes)
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "host/io/load.hpp"
#include "hwsim_eval.hpp"
#include "support/test_paths.hpp"

using namespace fs::host;

namespace {

int hwsim(double noise) {
  std::printf("| scene | GT faces (>2%%) | correct | over | under | missed | noise | max normal err (deg) | mean normal err (deg) | PFRG nodes | arcs known-known (expected) | ok |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (const char* name : {"pyramid", "cube", "cube-occludes-pyramid", "cube-pyramid-separate", "corner", "default"}) {
    const auto path = fs::test::source_dir() / "hw-sim/scenes" / (std::string(name) + ".json");
    if (!std::filesystem::exists(path)) continue;
    const auto ev = fs::test::evaluate_hwsim_scene(path, noise);
    const bool ok = ev.problems.empty() && ev.max_normal_error_deg < 1.0 &&
                    ev.graph.nodes.size() == ev.significant.size() + 1 && ev.actual_arcs == ev.expected_arcs;
    std::printf("| %s | %zu | %d | %d | %d | %d | %d | %.3f | %.3f | %zu | %zu (%zu) | %s |\n", name,
                ev.significant.size(), ev.significant_correct, ev.hoover.over, ev.hoover.under, ev.hoover.missed,
                ev.hoover.noise, ev.max_normal_error_deg, ev.hoover.mean_angle_error_deg, ev.graph.nodes.size(),
                ev.actual_arcs.size(), ev.expected_arcs.size(), ok ? "yes" : "NO");
    for (const auto& p : ev.problems) std::printf("  - %s\n", p.c_str());
  }
  return 0;
}

int mosd(std::vector<std::string> files) {
  if (files.empty())
    for (int k = 0; k < 24; ++k)
      files.push_back((fs::test::shared_data() / "mosd-boxes/test" / ("test" + std::to_string(k) + ".pcd")).string());
  std::printf("| file | known regions | pure regions | pure area share | PFRG nodes | arcs | ms |\n| --- | --- | --- | --- | --- | --- | --- |\n");
  double tot = 0, pure = 0;
  int worst_file = -1;
  double worst = 2;
  seg::Segmenter segmenter(seg::SegmentParams::kinect());
  seg::ScenePfrgBuilder builder;
  for (std::size_t f = 0; f < files.size(); ++f) {
    OrganizedCloud cloud;
    load_cloud(files[f], cloud);
    seg::Segmentation s;
    Pfrg g;
    const auto t0 = std::chrono::steady_clock::now();
    segmenter.segment(cloud, s);
    builder.build(s, g);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::vector<std::int32_t> obj(cloud.labels.size());
    for (std::size_t i = 0; i < obj.size(); ++i) obj[i] = seg::mosd_object(cloud.labels[i]);
    const auto sp = seg::object_span(obj, s);
    tot += sp.total_area;
    pure += sp.pure_area;
    if (sp.pure_fraction() < worst) {
      worst = sp.pure_fraction();
      worst_file = int(f);
    }
    std::printf("| %s | %d | %d | %.4f | %zu | %zu | %.1f |\n", std::filesystem::path(files[f]).filename().c_str(),
                sp.regions, sp.pure_regions, sp.pure_fraction(), g.nodes.size(), g.arcs.size(), ms);
  }
  std::printf("\nall files: pure area share %.4f; worst %s %.4f\n", tot > 0 ? pure / tot : 1.0,
              worst_file >= 0 ? files[std::size_t(worst_file)].c_str() : "-", worst);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string mode = argc > 1 ? argv[1] : "hwsim";
    if (mode == "hwsim") return hwsim(argc > 2 ? std::stod(argv[2]) : 0.05);
    if (mode == "mosd") return mosd(std::vector<std::string>(argv + 2, argv + argc));
    std::fprintf(stderr, "usage: segment_report hwsim [NOISE_MM] | mosd [FILES...]\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "segment_report: %s\n", e.what());
    return 1;
  }
}
