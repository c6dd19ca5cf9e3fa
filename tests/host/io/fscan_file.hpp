#pragma once
// Test helper: writes a synthetic or rendered scan as the firmware records it (.fscan: the wire frames
// ScanBegin, Stripe..., ScanEnd).
#include <filesystem>

#include "common/scan_file.hpp"
#include "synth_scan.hpp"

namespace fs::test {

inline void write_fscan(const std::filesystem::path& path, const SynthScan& s) {
  ScanFileWriter file{path};
  wire::FrameWriter w(file);
  w.send(s.begin);
  for (const auto& st : s.stripes) {
    msg::Stripe m;
    m.header = st.header;
    m.points = std::span<msg::StripePoint>(const_cast<msg::StripePoint*>(st.points.data()), st.points.size());
    w.send(m);
  }
  w.send(s.end);
  file.close();
}

}  // namespace fs::test
