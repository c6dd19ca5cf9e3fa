// libFuzzer target: the incremental frame decoder + message decoding on arbitrary bytes in arbitrary chunks.
// Properties checked beyond "no crash / no sanitizer report / only fs::Error":
//  * a frame that decodes (protocol 1.0, reserved byte 0) re-encodes to exactly the same bytes;
//  * the decoder never returns a frame larger than its limit, and offsets only grow.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>

#include "common/wire.hpp"

namespace {

template <class M>
void check_reencode(const fs::wire::FrameView& f, const M& m, std::span<std::uint8_t> scratch,
                    std::span<const std::uint8_t> original) {
  const std::size_t n = fs::wire::encode(scratch, f.header.sequence, m);
  if (n != original.size() || std::memcmp(scratch.data(), original.data(), n) != 0) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fs::wire::DecodedMessage msg;
  static std::uint8_t scratch[fs::wire::kMaxFrameSize];
  std::span<const std::uint8_t> in(data, size);
  // The first byte picks the chunk size, so the fuzzer explores feeding patterns too.
  std::size_t chunk = 1;
  if (!in.empty()) {
    chunk = 1 + in[0] * 97u;
    in = in.subspan(1);
  }
  const std::span<const std::uint8_t> stream = in;
  fs::wire::FrameDecoder dec("fuzz", fs::wire::DecoderLimits{16384});
  std::uint64_t last_offset = 0;
  int errors = 0;
  while (!in.empty() && errors < 16) {
    const std::size_t took = dec.feed(in.first(std::min(chunk, in.size())));
    in = in.subspan(took);
    for (;;) {
      try {
        fs::wire::FrameView f;
        if (!dec.next(f)) break;
        if (f.payload.size() > 16384 || f.offset < last_offset) std::abort();
        last_offset = f.offset;
        fs::wire::decode(f, msg, "fuzz");
        const auto original = stream.subspan(f.offset, fs::wire::kFrameOverhead + f.payload.size());
        if (f.header.minor == 0 && original[7] == 0) {
          switch (msg.type) {
            case fs::msg::Type::ScanBegin:
              check_reencode(f, msg.scan_begin, scratch, original);
              break;
            case fs::msg::Type::Stripe:
              check_reencode(f, msg.stripe, scratch, original);
              break;
            case fs::msg::Type::ScanEnd:
              check_reencode(f, msg.scan_end, scratch, original);
              break;
            case fs::msg::Type::Heartbeat:
              check_reencode(f, msg.heartbeat, scratch, original);
              break;
            case fs::msg::Type::Fault:
              check_reencode(f, msg.fault, scratch, original);
              break;
          }
        }
      } catch (const fs::Error&) {
        ++errors;
        if (dec.failed()) dec.resync();
      }
    }
  }
  try {
    dec.finish();
  } catch (const fs::Error&) {
  }
  return 0;
}
