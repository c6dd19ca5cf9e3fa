// facetscan-fw: the scanner board's firmware (galvo, laser, camera, stripe extraction, streaming).
#include <CLI/CLI.hpp>

#include "facetscan_version.hpp"

int main(int argc, char** argv) {
  CLI::App app{"facetscan-fw: laser-stripe scanner firmware"};
  app.set_version_flag("--version", std::string("facetscan-fw ") + fs::kVersion);
  CLI11_PARSE(app, argc, argv);
  return 0;
}
