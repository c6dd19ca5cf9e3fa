#pragma once
// Facetscan wire protocol: scanner -> host frames, used unchanged for the TCP stream and inside .fscan files.
//
// Frame layout (little-endian), kFrameHeaderSize = 16 bytes of header, payload, 4 bytes of CRC:
//   off  size  field
//     0     4  magic           "FSWF" (0x46 0x53 0x57 0x46)
//     4     1  version major   kProtocolMajor; a different major is rejected
//     5     1  version minor   kProtocolMinor; a newer minor is accepted (extra trailing payload is ignored)
//     6     1  message type    fs::msg::Type
//     7     1  reserved        0
//     8     4  payload length  <= FrameDecoder::Limits::max_payload (checked before the payload is read)
//    12     4  sequence        per-stream counter, +1 per frame (wraps)
//    16     N  payload         the message, field by field (see encode_payload / docs/formats.md)
//  16+N     4  CRC-32C         over header and payload (bytes 0 .. 16+N-1)
//
// Encoding writes into caller buffers; decoding is incremental (feed bytes in any chunking, pop whole
// frames) over one buffer allocated at construction: no allocation per frame. Errors are fs::Error with the
// stream name and the absolute byte offset of the offending field.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/error.hpp"
#include "common/messages.hpp"

namespace fs::wire {

inline constexpr std::array<std::uint8_t, 4> kMagic = {'F', 'S', 'W', 'F'};
inline constexpr std::uint8_t kProtocolMajor = 1;
inline constexpr std::uint8_t kProtocolMinor = 0;
inline constexpr std::size_t kFrameHeaderSize = 16;
inline constexpr std::size_t kFrameCrcSize = 4;
inline constexpr std::size_t kFrameOverhead = kFrameHeaderSize + kFrameCrcSize;

// Fixed payload sizes of this protocol version.
inline constexpr std::size_t kStripeHeaderSize = 48;  // StripeHeader fields + u32 point count
inline constexpr std::size_t kStripePointSize = 12;   // u16 row, f32 col, u16 peak, f32 width
inline constexpr std::size_t kMaxUnitsLength = 16;
// ScanBegin without the bytes of its two strings.
inline constexpr std::size_t kScanBeginFixedSize =
    8 + 2 + 8 + 8 * 9 + 8 * 9 + 8 * 3 + 8 * 12 + 4 + 4 + 8 * 4 + 1 + 2 + 8;
inline constexpr std::size_t kScanEndSize = 8 + 4 * 6 + 1 + 8 * 5 + 4 + 8 * 2;
inline constexpr std::size_t kHeartbeatSize = 8 + 8 + 1;
// The largest payload this version produces (a ScanBegin with maximal strings, a Stripe of
// kMaxStripePoints points, ...); the decoder's default limit.
inline constexpr std::size_t kMaxPayload = kStripeHeaderSize + kStripePointSize * msg::kMaxStripePoints;
inline constexpr std::size_t kMaxFrameSize = kMaxPayload + kFrameOverhead;
// Upper bound for DecoderLimits::max_payload (the decoder's buffer is max_payload + 20 bytes).
inline constexpr std::size_t kMaxConfigurablePayload = std::size_t{64} << 20;

const char* type_name(msg::Type t);
bool is_known_type(std::uint8_t t);

// ---- sinks
// -------------------------------------------------------------------------------------------------

// Where encoded bytes go: a TCP socket, a .fscan file, a buffer. write() writes all bytes or throws.
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual void write(std::span<const std::uint8_t> bytes) = 0;
};

// Appends to a std::vector (tests, tools; allocates as the vector grows).
class VectorSink final : public FrameSink {
 public:
  void write(std::span<const std::uint8_t> bytes) override {
    data.insert(data.end(), bytes.begin(), bytes.end());
  }
  std::vector<std::uint8_t> data;
};

// Writes every byte to two sinks (e.g. the TCP stream and a recording).
class TeeSink final : public FrameSink {
 public:
  TeeSink(FrameSink& a, FrameSink& b) : a_(a), b_(b) {}
  void write(std::span<const std::uint8_t> bytes) override {
    a_.write(bytes);
    b_.write(bytes);
  }

 private:
  FrameSink& a_;
  FrameSink& b_;
};

// ---- encoding
// ----------------------------------------------------------------------------------------------

// Payload sizes (bytes) of a message.
std::size_t payload_size(const msg::ScanBegin& m);
std::size_t payload_size(const msg::Stripe& m);
std::size_t payload_size(const msg::ScanEnd& m);
std::size_t payload_size(const msg::Heartbeat& m);
std::size_t payload_size(const msg::Fault& m);
template <class M>
std::size_t frame_size(const M& m) {
  return payload_size(m) + kFrameOverhead;
}

// Encode one whole frame into `out`; returns the number of bytes written (frame_size(m)). Throws fs::Error
// when `out` is too small or a field exceeds its maximum (strings, point count).
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t sequence, const msg::ScanBegin& m);
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t sequence, const msg::Stripe& m);
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t sequence, const msg::ScanEnd& m);
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t sequence, const msg::Heartbeat& m);
std::size_t encode(std::span<std::uint8_t> out, std::uint32_t sequence, const msg::Fault& m);

// Encodes messages with consecutive sequence numbers into one buffer allocated at construction and writes
// each frame to the sink. No allocation per frame.
class FrameWriter {
 public:
  explicit FrameWriter(FrameSink& sink, std::uint32_t first_sequence = 0,
                       std::size_t max_frame = kMaxFrameSize);
  template <class M>
  void send(const M& m) {
    const std::size_t n = encode(buffer_, seq_, m);
    sink_.write(std::span<const std::uint8_t>(buffer_.data(), n));
    ++seq_;
  }
  std::uint32_t next_sequence() const { return seq_; }
  FrameSink& sink() { return sink_; }

 private:
  FrameSink& sink_;
  std::vector<std::uint8_t> buffer_;
  std::uint32_t seq_;
};

// ---- decoding
// ----------------------------------------------------------------------------------------------

struct FrameHeader {
  std::uint8_t major = kProtocolMajor;
  std::uint8_t minor = kProtocolMinor;
  msg::Type type = msg::Type::Heartbeat;
  std::uint32_t payload_length = 0;
  std::uint32_t sequence = 0;
};

// A decoded frame; `payload` points into the decoder's buffer and stays valid until the next feed()/next().
struct FrameView {
  FrameHeader header;
  std::span<const std::uint8_t> payload;
  std::uint64_t offset = 0;  // absolute byte offset of the frame's first byte in the stream
};

// Parse a frame header (the first kFrameHeaderSize bytes); validates magic, major version, type and length.
// `offset` and `source` only label errors.
FrameHeader parse_header(std::span<const std::uint8_t> bytes, std::size_t max_payload,
                         const std::string& source, std::uint64_t offset);

// Decode a frame's payload into a message. The frame type must match (else fs::Error). Strings are assigned
// (no allocation when the target's capacity suffices, e.g. after DecodedMessage reserved them).
void decode(const FrameView& f, msg::ScanBegin& out, const std::string& source = "stream");
void decode(const FrameView& f, msg::ScanEnd& out, const std::string& source = "stream");
void decode(const FrameView& f, msg::Heartbeat& out, const std::string& source = "stream");
void decode(const FrameView& f, msg::Fault& out, const std::string& source = "stream");
// Stripe points are decoded into `storage`; out.points = the filled prefix. The point count is checked
// against kMaxStripePoints, storage.size() and the payload length before any point is read.
void decode(const FrameView& f, msg::Stripe& out, std::span<msg::StripePoint> storage,
            const std::string& source = "stream");

// Storage for any one decoded message, allocated once (strings reserved, kMaxStripePoints points).
struct DecodedMessage {
  DecodedMessage();
  msg::Type type = msg::Type::Heartbeat;
  std::uint32_t sequence = 0;
  std::uint64_t offset = 0;  // of the frame in the stream / file
  msg::ScanBegin scan_begin;
  msg::Stripe stripe;  // stripe.points views `point_storage`
  msg::ScanEnd scan_end;
  msg::Heartbeat heartbeat;
  msg::Fault fault;
  std::vector<msg::StripePoint> point_storage;
};
// Decodes f into the member of `out` named by its type.
void decode(const FrameView& f, DecodedMessage& out, const std::string& source = "stream");

// Incremental frame decoder. Typical use:
//   FrameDecoder dec("tcp 10.0.0.2:5555");
//   while (n = recv(...)) { auto in = span(buf, n);
//     while (!in.empty()) { in = in.subspan(dec.feed(in)); while (dec.next(frame)) handle(frame); } }
//   dec.finish();  // at end of stream: throws if a partial frame is left
// On a malformed frame next() throws fs::Error ("<source>: at byte N: ..."); the decoder then stays failed
// (next() rethrows the same error) until resync() (skip to the next magic) or reset().
struct DecoderLimits {
  std::size_t max_payload = kMaxPayload;  // frames with a longer payload are rejected from their header
};

class FrameDecoder {
 public:
  using Limits = DecoderLimits;
  explicit FrameDecoder(std::string source = "stream", Limits limits = Limits{},
                        std::uint64_t base_offset = 0);

  // Copies up to the free buffer space from `bytes`; returns how many bytes were taken (0 only when a whole
  // frame is waiting to be popped by next()).
  std::size_t feed(std::span<const std::uint8_t> bytes);
  // Pops the next complete frame. Returns false when more bytes are needed.
  bool next(FrameView& out);
  // End of stream: throws when buffered bytes do not form a whole frame ("truncated frame").
  void finish();
  // After an error: drop the bad byte and everything up to the next candidate magic. Returns bytes skipped.
  std::size_t resync();
  void reset(std::uint64_t base_offset = 0);

  std::uint64_t offset() const { return base_ + start_; }  // stream offset of the next undecoded byte
  std::uint64_t frames() const { return frames_; }
  std::size_t buffered() const { return end_ - start_; }
  bool failed() const { return failed_; }
  const std::string& source() const { return source_; }
  // Sequence continuity: number of frames whose sequence was not previous + 1 (lost frames on a live link).
  std::uint64_t sequence_gaps() const { return gaps_; }

 private:
  [[noreturn]] void fail(std::uint64_t at, const std::string& what);
  void compact();

  std::string source_;
  Limits limits_;
  std::vector<std::uint8_t> buf_;
  std::size_t start_ = 0, end_ = 0;
  std::uint64_t base_ = 0;  // stream offset of buf_[0]
  std::uint64_t frames_ = 0, gaps_ = 0;
  std::uint32_t last_seq_ = 0;
  bool have_seq_ = false;
  bool failed_ = false;
  std::string error_;
};

}  // namespace fs::wire
