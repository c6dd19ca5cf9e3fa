#pragma once
// Reading files of external input without trusting them: every reader of a configuration, parameter set,
// scene, calibration, mesh, point cloud, library or scan file opens it through here.
//  * the file is opened, then fstat()ed on the open descriptor (no race with a rename): anything but a
//    regular file (a device such as /dev/zero, a FIFO, a directory; a symbolic link to one) is refused:
//      "cfg.json: not a regular file (character device)";
//  * a file above the reader's cap is refused before a byte is read, naming the cap:
//      "cfg.json: 3.1 MB, more than the 1 MiB a firmware configuration may have";
//  * the read loop stops at the cap even if the file grows meanwhile.
// check_declared() is the second half: a count read from a header is checked against the bytes actually
// left in the file before anything is allocated for it.
// The caps (docs/formats.md, "Limits of each reader"):
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "common/byte_buffer.hpp"

namespace fs {

inline constexpr std::uint64_t kKiB = 1024, kMiB = 1024 * kKiB, kGiB = 1024 * kMiB;

// Firmware configuration, match parameters, calibration JSON, scene JSON.
inline constexpr std::uint64_t kMaxConfigFileBytes = 1 * kMiB;
// PFRG JSON (a graph of at most a few thousand nodes).
inline constexpr std::uint64_t kMaxGraphFileBytes = 64 * kMiB;
// Meshes (OFF, OBJ, STL, PLY) and .fslib libraries.
inline constexpr std::uint64_t kMaxMeshFileBytes = 1 * kGiB;
inline constexpr std::uint64_t kMaxLibraryFileBytes = 1 * kGiB;
// Point clouds (PCD, PLY): 2^26 points of ascii text fit.
inline constexpr std::uint64_t kMaxCloudFileBytes = 4 * kGiB;

// Sizes for messages: "150 bytes" below 10,000, else decimal units with one decimal ("1.6 GB").
std::string format_bytes(std::uint64_t bytes);
// A cap: "1 MiB", "4 GiB" (whole binary multiples), else as format_bytes.
std::string format_cap(std::uint64_t bytes);

// What the file at `path` is, for messages: "regular file", "directory", "character device", "FIFO", ...
std::string file_type_name(unsigned st_mode);

// Opens `path` for reading and checks it is a regular file of at most max_bytes (what: the kind of file,
// e.g. "firmware configuration", used in the message). Returns the descriptor (the caller closes it) and
// stores the size. Throws fs::Error naming the path.
int open_input_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what,
                    std::uint64_t& size);

// The whole file, checked as by open_input_file.
std::string read_input_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                            std::string_view what);
// Large files land in a buffer on transparent huge pages (common/byte_buffer.hpp).
ByteBuffer read_input_bytes(const std::filesystem::path& path, std::uint64_t max_bytes,
                            std::string_view what);

// A count declared by a file (`field`, e.g. "POINTS") of elements of at least element_bytes bytes each must
// fit in the bytes_left bytes that follow; otherwise throws
//   "<source>: POINTS 100000000 x 16 bytes = 1.6 GB but the file has 150 bytes after the header".
// `after` names where the bytes are counted from ("after the header").
void check_declared(const std::string& source, std::string_view field, std::uint64_t declared,
                    std::uint64_t element_bytes, std::uint64_t bytes_left,
                    std::string_view after = "after the header");

}  // namespace fs
