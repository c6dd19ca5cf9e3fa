#pragma once
// .fscan images in memory (a scan received over NATS, host/fleet/): the same reader, assembler and
// triangulation as a .fscan file (scan_assembler.hpp, load.hpp), and the encoder of a Scan into an image
// (the bytes write_scan_file would write). `name` labels errors: "<name>: at byte N: ...".
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/messages.hpp"
#include "host/io/load.hpp"
#include "host/io/organized_cloud.hpp"
#include "host/io/scan.hpp"

namespace fs::host {

// The first scan of an image into `out`; throws fs::Error when the image has no scan or is malformed.
void load_scan_bytes(std::span<const std::uint8_t> image, const std::string& name, Scan& out,
                     const ScanLimits& limits = {});

// load_cloud for a .fscan image: the first scan, triangulated with its ScanBegin's calibration.
LoadInfo load_cloud_bytes(std::span<const std::uint8_t> image, const std::string& name, OrganizedCloud& out,
                          const LoadOptions& options = {});

// The ScanBegin of an image's first scan (scan id, start time, scanner model) without reading the stripes.
msg::ScanBegin peek_scan_begin(std::span<const std::uint8_t> image, const std::string& name);

// A Scan as a .fscan image (file header, ScanBegin, the kept stripes in step order, ScanEnd when it has one).
std::vector<std::uint8_t> encode_scan_bytes(const Scan& scan);

}  // namespace fs::host
