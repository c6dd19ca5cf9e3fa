// libFuzzer target: a scanner's byte stream into `facetscan serve`'s state machine, the same classes serve
// uses (host/io/stream_server.cpp): wire::FrameDecoder -> wire::decode -> ScanAssembler, with the stream cut
// into chunks and the connection dropped / re-dialled / cut by a protocol error where the input says.
//
// Input layout (so that a seed is a real frame stream with a short prefix and suffix):
//   byte 0      chunk size selector: chunks of 1 + b0 * 61 bytes
//   byte 1      n = number of control bytes (0..31 used) at the END of the input
//   bytes 2..   the frame stream
//   last n      control bytes; after chunk k, control[k % n] (low 2 bits) says what happens next:
//                 0 nothing, 1 the scanner disconnects and re-dials (end_of_stream(Disconnected), decoder
//                 reset), 2 the link times out after a protocol cut (end_of_stream(ProtocolError)),
//                 3 a heartbeat from the host side only (nothing for the assembler)
// A decode error drops the connection as serve does (a scan in progress ends ProtocolError when a new
// ScanBegin comes instead of a resume) and the rest of the chunk is discarded; after 16 errors the input
// ends (the scanner gives up).
// Checks beyond "no crash / only fs::Error": every delivered scan is finished (not InProgress), within the
// limits, and complete only with a ScanEnd; complete + partial counts equal the deliveries; no scan is in
// progress after end_of_stream().
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "common/error.hpp"
#include "common/wire.hpp"
#include "host/io/scan_assembler.hpp"

namespace {

struct Counters {
  std::uint64_t delivered = 0;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fs::wire::DecodedMessage message;
  std::span<const std::uint8_t> in(data, size);
  if (in.size() < 2) return 0;
  const std::size_t chunk = 1 + std::size_t(in[0]) * 61;
  const std::size_t nctrl = std::min<std::size_t>(in[1] & 31u, in.size() - 2);
  const std::span<const std::uint8_t> control = in.last(nctrl);
  std::span<const std::uint8_t> stream = in.subspan(2, in.size() - 2 - nctrl);

  fs::host::ScanLimits limits;
  limits.max_steps = 4096;
  limits.max_total_points = 1u << 16;
  Counters counters;
  fs::host::ScanAssembler assembler(
      [&](const fs::host::Scan& s) {
        ++counters.delivered;
        if (s.status() == fs::host::ScanStatus::InProgress) std::abort();
        if (s.points_stored() > limits.max_total_points) std::abort();
        if (s.slot_count() > limits.max_steps) std::abort();
        if (s.complete() && !s.has_end()) std::abort();  // complete means a ScanEnd said so
      },
      limits);
  fs::wire::FrameDecoder decoder("fuzz", fs::wire::DecoderLimits{16384});
  bool protocol_cut = false;  // StreamServer::protocol_cut_
  auto on_frame = [&] {
    if (protocol_cut && message.type == fs::msg::Type::ScanBegin)
      assembler.end_of_stream(fs::host::ScanStatus::ProtocolError);
    if (message.type != fs::msg::Type::Heartbeat) protocol_cut = false;
    assembler.on_message(message);
  };
  int errors = 0;  // each one is a dropped connection; a few are enough (exceptions are slow)
  for (std::size_t k = 0; !stream.empty() && errors < 16; ++k) {
    std::span<const std::uint8_t> piece = stream.first(std::min(chunk, stream.size()));
    stream = stream.subspan(piece.size());
    try {
      while (!piece.empty()) {
        piece = piece.subspan(decoder.feed(piece));
        fs::wire::FrameView f;
        while (decoder.next(f)) {
          fs::wire::decode(f, message, decoder.source());
          on_frame();
        }
      }
    } catch (const fs::Error&) {
      // serve drops the client; the scanner re-dials and the decoder starts afresh.
      if (assembler.in_scan()) protocol_cut = true;
      decoder.reset(0);
      ++errors;
    }
    if (nctrl == 0) continue;
    switch (control[k % nctrl] & 3u) {
      case 1:
        assembler.end_of_stream(protocol_cut ? fs::host::ScanStatus::ProtocolError
                                             : fs::host::ScanStatus::Disconnected);
        decoder.reset(0);
        break;
      case 2:
        assembler.end_of_stream(fs::host::ScanStatus::ProtocolError);
        break;
      default:
        break;
    }
    if ((control[k % nctrl] & 3u) != 0 && (control[k % nctrl] & 3u) != 3 && assembler.in_scan()) std::abort();
  }
  assembler.end_of_stream();
  if (assembler.in_scan()) std::abort();
  const auto& st = assembler.stats();
  if (st.scans_complete + st.scans_partial != counters.delivered) std::abort();
  return 0;
}
