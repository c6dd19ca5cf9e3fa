#pragma once
// A Scan written back as a .fscan file (common/scan_file.hpp) with the wire encoder: its ScanBegin, the
// stripes it kept (one per step, in step order; of a repeated step the newer), and its ScanEnd when it has
// one. `facetscan recognize` reads it like a recording. What a Scan does not keep is not written: Fault
// frames (the scan keeps only their count), heartbeats, rejected stripes. serve keeps failed scans this way.
#include <filesystem>

#include "common/messages.hpp"
#include "common/wire.hpp"
#include "host/io/scan.hpp"

namespace fs::host {

// The frames of a scan (ScanBegin, the kept stripes in step order, ScanEnd when it has one) into a sink.
void write_scan_frames(wire::FrameSink& sink, const Scan& scan);

// Writes `scan` to `path` (created / truncated). Throws fs::Error naming the path on I/O errors.
void write_scan_file(const std::filesystem::path& path, const Scan& scan);
// A scan of which only the ScanBegin is known (refused by the limits): the file holds that ScanBegin.
void write_scan_file(const std::filesystem::path& path, const msg::ScanBegin& begin);

}  // namespace fs::host
