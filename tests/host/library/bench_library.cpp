// Benchmarks: building models, computing symmetry groups, loading .fslib files, partial views.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "common/mesh.hpp"
#include "host/library/library.hpp"
#include "host/library/polycubes.hpp"
#include "host/library/views.hpp"
#include "support/test_paths.hpp"

namespace {

namespace stdfs = std::filesystem;

fs::host::Library polyhedra_library() {
  fs::host::Library lib;
  for (const auto& e : stdfs::directory_iterator(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off"))
    lib.add(fs::host::build_model(fs::read_mesh(e.path())));
  return lib;
}

// All polycubes up to `volume` (edge 20 mm), as `facetscan library polycubes` makes them.
fs::host::Library polycube_library(int volume) {
  fs::host::Library lib;
  for (auto& m : fs::host::polycube_models(fs::host::enumerate_polycubes(volume), 20)) lib.add(std::move(m));
  return lib;
}

void BM_BuildAllPolyhedra(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(polyhedra_library());
  state.SetLabel("120 OFF solids: read + build_model (incl. symmetry)");
}
BENCHMARK(BM_BuildAllPolyhedra)->Unit(benchmark::kMillisecond);

void BM_LoadPolyhedraLibrary(benchmark::State& state) {
  const auto bytes = polyhedra_library().to_bytes();
  for (auto _ : state) benchmark::DoNotOptimize(fs::host::Library::from_bytes(bytes, "bench"));
  state.SetLabel(std::to_string(bytes.size()) + " bytes, 120 models");
}
BENCHMARK(BM_LoadPolyhedraLibrary)->Unit(benchmark::kMillisecond);

// The 8,152 polycubes of volume <= 8 with their arc index, from memory (what `-l cubes8.fslib` reads after
// the file): CRC, parse and validation, index; the library freed outside the timing.
void BM_LoadPolycubeLibrary8(benchmark::State& state) {
  const auto bytes = polycube_library(8).to_bytes();
  for (auto _ : state) {
    auto loaded = fs::host::Library::from_bytes(bytes, "bench");
    state.PauseTiming();
    loaded = {};
    state.ResumeTiming();
  }
  state.SetLabel(std::to_string(bytes.size()) + " bytes, 8152 models");
}
BENCHMARK(BM_LoadPolycubeLibrary8)->Unit(benchmark::kMillisecond);

void BM_EnumeratePolycubes(benchmark::State& state) {
  for (auto _ : state)
    benchmark::DoNotOptimize(fs::host::enumerate_polycubes(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_EnumeratePolycubes)->Arg(6)->Arg(8)->Unit(benchmark::kMillisecond);

void BM_PolycubeLibrary6(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(polycube_library(6));
}
BENCHMARK(BM_PolycubeLibrary6)->Unit(benchmark::kMillisecond);

void BM_SymmetrySnubDodecahedron(benchmark::State& state) {
  const auto m = fs::host::build_model(
      fs::read_mesh(fs::test::shared_data() / "polyhedra/polyhedra-viewer/off/snub-dodecahedron.off"));
  for (auto _ : state) benchmark::DoNotOptimize(fs::host::compute_symmetries(m));
}
BENCHMARK(BM_SymmetrySnubDodecahedron)->Unit(benchmark::kMicrosecond);

void BM_PartialView(benchmark::State& state) {
  const auto m = fs::host::build_model(fs::read_mesh(
      fs::test::shared_data() / "polyhedra/polyhedra-viewer/off/truncated-icosidodecahedron.off"));
  const fs::Mat3 R = Eigen::AngleAxisd(0.3, fs::Vec3(1, 2, 3).normalized()).toRotationMatrix();
  for (auto _ : state) benchmark::DoNotOptimize(fs::host::partial_view(m, R, fs::Vec3(0, 0, -1)));
}
BENCHMARK(BM_PartialView)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
