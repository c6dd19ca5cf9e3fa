#include "host/io/scan_writer.hpp"

#include "common/scan_file.hpp"
#include "common/wire.hpp"

namespace fs::host {

void write_scan_frames(wire::FrameSink& sink, const Scan& scan) {
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
}

void write_scan_file(const std::filesystem::path& path, const Scan& scan) {
  ScanFileWriter file(path);
  write_scan_frames(file, scan);
  file.close();
}

void write_scan_file(const std::filesystem::path& path, const msg::ScanBegin& begin) {
  ScanFileWriter file(path);
  wire::FrameWriter w(file);
  w.send(begin);
  file.close();
}

}  // namespace fs::host
