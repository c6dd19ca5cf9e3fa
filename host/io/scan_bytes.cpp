#include "host/io/scan_bytes.hpp"

#include <array>

#include "common/error.hpp"
#include "common/scan_file.hpp"
#include "common/wire.hpp"
#include "host/io/scan_assembler.hpp"
#include "host/io/scan_writer.hpp"

namespace fs::host {

void load_scan_bytes(std::span<const std::uint8_t> image, const std::string& name, Scan& out,
                     const ScanLimits& limits) {
  ScanFileReader reader(image, name);
  load_first_scan(reader, name, out, limits);
}

LoadInfo load_cloud_bytes(std::span<const std::uint8_t> image, const std::string& name, OrganizedCloud& out,
                          const LoadOptions& options) {
  Scan scan;
  load_scan_bytes(image, name, scan, options.limits);
  return triangulate_loaded_scan(scan, name, options, out);
}

msg::ScanBegin peek_scan_begin(std::span<const std::uint8_t> image, const std::string& name) {
  ScanFileReader reader(image, name);
  wire::DecodedMessage m;
  while (reader.next(m))
    if (m.type == msg::Type::ScanBegin) return m.scan_begin;
  throw Error(name + ": no scan in the image (no ScanBegin)");
}

std::vector<std::uint8_t> encode_scan_bytes(const Scan& scan) {
  wire::VectorSink sink;
  std::array<std::uint8_t, kScanFileHeaderSize> header{};
  encode_scan_file_header(header);
  sink.write(header);
  write_scan_frames(sink, scan);
  return std::move(sink.data);
}

}  // namespace fs::host
