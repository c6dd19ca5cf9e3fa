#include "host/io/scan_assembler.hpp"

#include "common/error.hpp"
#include "common/scan_file.hpp"

namespace fs::host {

ScanAssembler::ScanAssembler(Callback on_scan, ScanLimits limits)
    : on_scan_(std::move(on_scan)), limits_(limits) {}

void ScanAssembler::on_message(const wire::DecodedMessage& m) {
  switch (m.type) {
    case msg::Type::ScanBegin:
      on_scan_begin(m.scan_begin);
      break;
    case msg::Type::Stripe:
      on_stripe(m.stripe);
      break;
    case msg::Type::ScanEnd:
      on_scan_end(m.scan_end);
      break;
    case msg::Type::Heartbeat:
      on_heartbeat(m.heartbeat);
      break;
    case msg::Type::Fault:
      on_fault(m.fault);
      break;
  }
}

void ScanAssembler::deliver() {
  if (scan_.complete())
    ++stats_.scans_complete;
  else
    ++stats_.scans_partial;
  if (on_scan_) on_scan_(scan_);
}

void ScanAssembler::on_scan_begin(const msg::ScanBegin& m) {
  if (in_scan()) {
    scan_.interrupt(ScanStatus::Superseded);
    deliver();
  }
  scan_.start(m, limits_);
}

void ScanAssembler::on_stripe(const msg::Stripe& m) {
  if (!in_scan() || m.header.scan_id != scan_.scan_id()) {
    ++stats_.orphan_stripes;
    return;
  }
  scan_.add_stripe(m);
}

void ScanAssembler::on_scan_end(const msg::ScanEnd& m) {
  if (!in_scan() || m.scan_id != scan_.scan_id()) {
    ++stats_.orphan_stripes;
    return;
  }
  scan_.finish(m);
  deliver();
}

void ScanAssembler::on_heartbeat(const msg::Heartbeat& m) {
  ++stats_.heartbeats;
  stats_.last_heartbeat_ns = m.time_ns;
  stats_.last_state = m.state;
}

void ScanAssembler::on_fault(const msg::Fault& m) {
  ++stats_.faults;
  if (in_scan()) scan_.note_fault(m);
}

void ScanAssembler::end_of_stream(ScanStatus why) {
  if (in_scan()) {
    scan_.interrupt(why);
    deliver();
  }
}

namespace {

void feed_scan_file(ScanFileReader& reader, const std::string& name, ScanAssembler& assembler) {
  wire::DecodedMessage m;
  while (reader.next(m)) {
    try {
      assembler.on_message(m);
    } catch (const Error& e) {
      throw error_at_offset(name, m.offset, e.what());
    }
  }
  assembler.end_of_stream();
}

void feed_scan_file(const std::string& path, ScanAssembler& assembler) {
  ScanFileReader reader{std::filesystem::path(path)};
  feed_scan_file(reader, path, assembler);
}

}  // namespace

std::size_t read_scan_file(const std::string& path, const ScanAssembler::Callback& on_scan,
                           const ScanLimits& limits) {
  std::size_t n = 0;
  ScanAssembler assembler(
      [&](const Scan& s) {
        ++n;
        on_scan(s);
      },
      limits);
  feed_scan_file(path, assembler);
  return n;
}

void load_first_scan(ScanFileReader& reader, const std::string& name, Scan& out, const ScanLimits& limits) {
  // The first scan is moved out of the assembler when it is delivered (no second copy of its points; the
  // assembler goes on with a fresh Scan); later scans in the file are read (validated) but not kept.
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
  feed_scan_file(reader, name, assembler);
  if (!kept) throw Error(name + ": no scan in the file (no ScanBegin)");
}

void load_scan(const std::string& path, Scan& out, const ScanLimits& limits) {
  ScanFileReader reader{std::filesystem::path(path)};
  load_first_scan(reader, path, out, limits);
}

}  // namespace fs::host
