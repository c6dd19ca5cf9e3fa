#include "hw-sim/scene/sim_frame_cli.hpp"

#include <cmath>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common/error.hpp"
#include "common/png_write.hpp"
#include "hw-sim/scene/scene.hpp"
#include "hw-sim/scene/stripe_renderer.hpp"

namespace fs::sim {
namespace {

struct SimFrameArgs {
  std::string scene;
  double step = 0.0;
  std::string output;
  double noise = 1.0;
  double speckle_grain = 0.0;
  std::uint64_t seed = 1;
  bool mono16 = false;
  bool reflection = false;
  std::string truth;
};

void write_truth_csv(const std::string& path, std::span<const StripeSample> rows) {
  std::ofstream out(path);
  if (!out) throw Error(path + ": cannot write ground truth");
  out << "row,column,x,y,z,object,face\n";
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const StripeSample& s = rows[r];
    if (!s.valid()) continue;
    out << fmt::format("{},{:.6f},{:.6f},{:.6f},{:.6f},{},{}\n", r, s.column, s.point.x(), s.point.y(),
                       s.point.z(), s.object, s.face);
  }
  if (!out) throw Error(path + ": write error");
}

void run(const SimFrameArgs& a) {
  const Scene scene = load_scene(a.scene);
  RenderOptions opt;
  opt.noise_scale = a.noise;
  opt.spurious_reflection = a.reflection;
  opt.speckle_grain_px = a.speckle_grain;
  StripeRenderer renderer(scene, opt);
  const CameraModel& cam = scene.calibration.camera;
  FrameBuffer fb;
  fb.width = cam.width;
  fb.height = cam.height;
  fb.format = a.mono16 ? FrameFormat::Mono16 : FrameFormat::Mono8;
  fb.stride = cam.width * (a.mono16 ? 2 : 1);
  std::vector<std::uint16_t> pixels(static_cast<std::size_t>(fb.stride) * cam.height / 2 + 1);
  fb.data = reinterpret_cast<std::uint8_t*>(pixels.data());
  renderer.render_step(a.step, a.seed, fb);
  if (a.mono16) {
    write_png_gray16(
        a.output, cam.width, cam.height,
        std::span<const std::uint16_t>(pixels.data(), static_cast<std::size_t>(cam.width) * cam.height),
        cam.width);
  } else {
    write_png_gray8(a.output, cam.width, cam.height,
                    std::span<const std::uint8_t>(fb.data, static_cast<std::size_t>(fb.stride) * cam.height),
                    fb.stride);
  }
  if (!a.truth.empty()) write_truth_csv(a.truth, renderer.truth());
  std::size_t rows = 0;
  for (const StripeSample& s : renderer.truth()) rows += s.valid() ? 1 : 0;
  fmt::print("{}: step {} (mirror {:.6f} rad), {} rows with stripe, {}x{} {}\n", a.output, a.step,
             scene.calibration.laser.mirror_angle(a.step), rows, cam.width, cam.height,
             a.mono16 ? "Mono16" : "Mono8");
}

}  // namespace

void add_sim_frame_command(CLI::App& app) {
  auto args = std::make_shared<SimFrameArgs>();
  CLI::App* sub = app.add_subcommand("sim-frame", "Render one simulated stripe frame of a scene to PNG");
  sub->add_option("--scene", args->scene, "Scene JSON (e.g. hw-sim/scenes/default.json)")->required();
  sub->add_option("--step", args->step, "Galvo step (fractional steps allowed)")->required();
  sub->add_option("-o,--output", args->output, "Output PNG")->required();
  sub->add_option("--noise", args->noise, "Noise scale: 0 = noise-free, 1 = default sensor noise and speckle")
      ->check(CLI::NonNegativeNumber);
  sub->add_option(
         "--speckle-grain", args->speckle_grain,
         "Correlation length of the speckle (px, along rows and between them; 0 = independent per pixel)")
      ->check(CLI::Range(0.0, kMaxSpeckleGrainPx));
  sub->add_option("--seed", args->seed, "Noise seed (same seed, same frame)");
  sub->add_flag("--mono16", args->mono16, "16-bit frame instead of 8-bit");
  sub->add_flag("--reflection", args->reflection, "Add a spurious reflection next to the stripe on objects");
  sub->add_option("--truth", args->truth, "Also write the per-row ground truth as CSV");
  sub->callback([args] { run(*args); });
}

}  // namespace fs::sim
