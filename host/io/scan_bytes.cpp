#include "host/io/scan_bytes.hpp"

#include <array>

#include "common/error.hpp"
#include "common/scan_file.hpp"
#include "common/wire.hpp"
#include "host/io/scan_assembler.hpp"
#include "host/io/triangulate.hpp"

namespace fs::host {

void load_scan_bytes(std::span<const std::uint8_t> image, const std::string& name, Scan& out,
                     const ScanLimits& limits) {
  // As load_scan: the first scan is moved out of the assembler; later scans are validated, not kept.
  bool kept = false;
  ScanAssembler* self = nullptr;
  ScanAssembler assembler(
      [&](const Scan&) {
        if (kept) return;
        out = std::move(self->storage());
        self->storage() = Scan();
        kept = true;
      },
      limits);
  self = &assembler;
  ScanFileReader reader(image, name);
  wire::DecodedMessage m;
  while (reader.next(m)) {
    try {
      assembler.on_message(m);
    } catch (const Error& e) {
      throw error_at_offset(name, m.offset, e.what());
    }
  }
  assembler.end_of_stream();
  if (!kept) throw Error(name + ": no scan in the image (no ScanBegin)");
}

LoadInfo load_cloud_bytes(std::span<const std::uint8_t> image, const std::string& name, OrganizedCloud& out,
                          const LoadOptions& options) {
  LoadInfo info;
  Scan scan;
  load_scan_bytes(image, name, scan, options.limits);
  TriangulationOptions to = options.triangulation;
  to.limits = options.limits;
  Triangulator tri;
  try {
    tri.configure(scan.begin_message().calibration, to);
  } catch (const Error& e) {
    throw Error(name + ": " + e.what());
  }
  info.triangulation = tri.triangulate(scan, out);
  info.format = "fscan";
  info.complete_scan = scan.complete();
  info.scan_status = to_string(scan.status());
  info.stripe_points = scan.points_stored();
  info.stripes_over_budget = scan.stripes_over_budget();
  info.valid_points = out.valid_count();
  return info;
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
  wire::FrameWriter w(sink);
  w.send(scan.begin_message());
  for (std::uint32_t k = 0; k < scan.slot_count(); ++k) {
    if (!scan.has_stripe(k)) continue;
    const auto points = scan.stripe_points(k);
    msg::Stripe m;
    m.header = scan.stripe_header(k);
    // Encoding only reads the points.
    m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(points.data()), points.size());
    w.send(m);
  }
  if (scan.has_end()) w.send(scan.end_message());
  return std::move(sink.data);
}

}  // namespace fs::host
