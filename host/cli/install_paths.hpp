#pragma once
// Where the host program finds what ships with it: the folder of the running binary (facetscan-fw-hil sits
// next to facetscan) and the shipped scenes (next to the sources, or installed).
#include <filesystem>

namespace fs::host::cli {

// The running program's folder (/proc/self/exe), or the current folder when that cannot be read.
std::filesystem::path self_dir();
// hw-sim/scenes of the sources, else /usr/share/facetscan/scenes; throws fs::Error naming both.
std::filesystem::path scenes_dir();

}  // namespace fs::host::cli
