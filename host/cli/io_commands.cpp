// facetscan export / calibrate (the io area).
#include <iostream>
#include <memory>

#include "host/cli/commands.hpp"
#include "host/io/io_tools.hpp"

namespace fs::host::cli {

void add_io_commands(CLI::App& app) {
  {
    auto args = std::make_shared<ExportArgs>();
    auto units = std::make_shared<std::string>("auto");
    auto encoding = std::make_shared<std::string>("binary_compressed");
    auto* cmd = app.add_subcommand("export", "Write a scan or point cloud as an organized PLY or PCD file");
    cmd->add_option("input", args->input, "SCAN.fscan | CLOUD.pcd | CLOUD.ply")->required();
    cmd->add_option("-o,--output", args->output, "cloud.ply | cloud.pcd")->required();
    cmd->add_option("--units", *units, "Input units of PCD/PLY: auto (metres if all |coords| < 20), mm, m")
        ->capture_default_str();
    cmd->add_option("--scale", args->load.scale, "Millimetres per input unit (overrides --units)");
    cmd->add_flag("--colour-labels,--color-labels", args->write.colours_from_labels,
                  "Colour points by their label (rgb field / red green blue)");
    cmd->add_flag("!--no-labels", args->write.write_labels, "Do not write the label field");
    cmd->add_option("--pcd-encoding", *encoding, "ascii | binary | binary_compressed")->capture_default_str();
    cmd->add_flag("--ply-ascii", args->write.ply_ascii, "Write ascii PLY instead of binary little endian");
    cmd->add_option("--min-angle", args->load.triangulation.min_ray_plane_angle_deg,
                    "Scans: reject rays within this many degrees of the laser plane")
        ->capture_default_str();
    cmd->callback([args, units, encoding] {
      args->load.units = parse_units(*units);
      args->pcd_encoding = parse_pcd_encoding(*encoding);
      run_export(*args, std::cout);
    });
  }
  {
    auto args = std::make_shared<CalibrateArgs>();
    auto* cmd = app.add_subcommand(
        "calibrate", "Estimate the laser plane model from scans of a flat target at known heights");
    cmd->add_option("--target", args->targets, "SCAN.fscan@HEIGHT_MM (repeat; at least two heights)")
        ->required();
    cmd->add_option("--nominal", args->nominal,
                    "Starting calibration JSON (default: the first scan's header)");
    cmd->add_option("-o,--output", args->output, "Calibration JSON to write");
    cmd->add_option("--row-stride", args->options.row_stride, "Use every n-th stripe point")
        ->capture_default_str();
    cmd->add_option("--max-iterations", args->options.max_iterations, "Levenberg-Marquardt iterations")
        ->capture_default_str();
    cmd->add_option("--outlier-mm", args->options.outlier_mm,
                    "Drop points this far from their target after init")
        ->capture_default_str();
    cmd->add_flag("!--no-linear-init", args->options.linear_init, "Start from the nominal model");
    cmd->callback([args] { run_calibrate(*args, std::cout); });
  }
}

}  // namespace fs::host::cli
