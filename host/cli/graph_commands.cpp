// facetscan graph SCAN|CLOUD -o graph.json [--pictures DIR] [--preset auto|laser|kinect]
#include <cstdio>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "host/cli/commands.hpp"
#include "host/io/load.hpp"
#include "host/pfrg/pfrg.hpp"
#include "host/segment/pictures.hpp"
#include "host/segment/scene_pfrg.hpp"
#include "host/segment/segmenter.hpp"

namespace fs::host::cli {
namespace {

struct GraphOptions {
  std::string input;
  std::string output;
  std::string pictures;
  std::string preset = "auto";
  bool quiet = false;
};

void run_graph(const GraphOptions& o) {
  OrganizedCloud cloud;
  const LoadInfo info = load_cloud(o.input, cloud);
  seg::SegmentParams params;
  std::string preset = o.preset;
  if (preset == "auto") preset = (info.format != "fscan" && info.scale >= 999.0) ? "kinect" : "laser";
  if (!seg::SegmentParams::by_name(preset, params))
    throw Error("--preset: unknown preset '" + o.preset + "' (auto, laser, kinect)");
  seg::SegmentLimits limits;
  limits.max_cells = cloud.points.size();
  seg::Segmenter segmenter(params, limits);
  seg::Segmentation s;
  Pfrg g;
  g.name = std::filesystem::path(o.input).stem().string();
  seg::PreprocessStats st;
  seg::ScenePfrgBuilder builder(limits.max_regions, limits.max_borders);
  try {
    segmenter.prepare(s);
    segmenter.segment(cloud, s);
    builder.build(s, g, &st);
  } catch (const Error& e) {
    // Segmentation and graph errors ("segment: viewpoint is not finite") name the input.
    const std::string what = e.what();
    if (what.rfind(o.input + ":", 0) == 0) throw;
    throw Error(o.input + ": " + what);
  }
  if (o.output == "-") {
    std::printf("%s\n", to_json(g).dump(1).c_str());
  } else {
    write_pfrg_json(g, o.output);
  }
  if (!o.pictures.empty()) {
    Vec3 c = Vec3::Zero();
    double wsum = 0;
    for (const auto& n : g.nodes) {
      if (n.supernode) continue;
      c += n.area * n.centroid;
      wsum += n.area;
    }
    if (wsum > 0) c /= wsum;
    seg::write_pictures(s, g, cloud.viewpoint - c, o.pictures);
  }
  if (!o.quiet) {
    std::fprintf(
        stderr,
        "graph: %s: %ux%u grid (%zu valid), preset %s: %d known + %d unknown regions, %zu borders; "
        "%d border regions eliminated, %d null nodes -> supernode, %d dropped; PFRG %zu nodes, %zu arcs%s\n",
        o.input.c_str(), cloud.width, cloud.height, info.valid_points, preset.c_str(), st.known_regions,
        st.unknown_regions, s.borders.size(), st.border_regions_eliminated, st.null_nodes_to_supernode,
        st.null_nodes_dropped, g.nodes.size(), g.arcs.size(), s.truncated ? " (budget exhausted)" : "");
  }
}

}  // namespace

void add_graph_commands(CLI::App& app) {
  auto opts = std::make_shared<GraphOptions>();
  CLI::App* cmd = app.add_subcommand(
      "graph", "Segment a scan or organized cloud into planar faces and write the scene PFRG (JSON)");
  cmd->add_option("input", opts->input, "scan (.fscan) or organized cloud (.pcd, .ply)")->required();
  cmd->add_option("-o,--output", opts->output, "PFRG JSON output file ('-' = stdout)")->required();
  cmd->add_option("--pictures", opts->pictures,
                  "write segmentation.png, pfrg.svg, enm.svg into this directory");
  cmd->add_option("--preset", opts->preset, "segmentation parameters: auto (default), laser, kinect");
  cmd->add_flag("-q,--quiet", opts->quiet, "no summary on stderr");
  cmd->callback([opts] { run_graph(*opts); });
}

}  // namespace fs::host::cli
