#pragma once
// The .fscan scan file: a 16-byte file header followed by the wire frame stream (common/wire.hpp), exactly
// as it came over TCP. Recording a live stream = writing the header, then every received byte.
//
// File header (little-endian):
//   off size field
//     0    8 magic        "FSCAN\r\n\x1a" (46 53 43 41 4E 0D 0A 1A; catches text-mode mangling)
//     8    2 format major kScanFileMajor; a different major is rejected
//    10    2 format minor kScanFileMinor; newer minors are accepted
//    12    4 header size  >= 16; the frames start at this offset (room for future header fields)
#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "common/wire.hpp"

namespace fs {

inline constexpr std::array<std::uint8_t, 8> kScanFileMagic = {'F', 'S', 'C', 'A', 'N', '\r', '\n', 0x1a};
inline constexpr std::uint16_t kScanFileMajor = 1;
inline constexpr std::uint16_t kScanFileMinor = 0;
inline constexpr std::size_t kScanFileHeaderSize = 16;
inline constexpr std::uint32_t kScanFileMaxHeaderSize = 4096;

// Encodes the file header into out (>= kScanFileHeaderSize bytes).
void encode_scan_file_header(std::span<std::uint8_t, kScanFileHeaderSize> out);
// Validates a file header; returns the offset of the first frame. Throws fs::Error naming `source` and
// offset.
std::uint32_t parse_scan_file_header(std::span<const std::uint8_t> bytes, const std::string& source);

// Writes a .fscan file. It is a wire::FrameSink: use it with wire::FrameWriter (encode messages) or write raw
// received stream bytes into it (recording a live stream). Creates/truncates the file and writes the header.
class ScanFileWriter final : public wire::FrameSink {
 public:
  explicit ScanFileWriter(const std::filesystem::path& path);
  ~ScanFileWriter() override;
  ScanFileWriter(const ScanFileWriter&) = delete;
  ScanFileWriter& operator=(const ScanFileWriter&) = delete;

  void write(std::span<const std::uint8_t> bytes) override;  // throws fs::Error on I/O errors
  void flush();
  void close();  // flush + close; throws on error. The destructor closes silently.
  std::uint64_t bytes_written() const { return written_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  std::FILE* f_ = nullptr;
  std::uint64_t written_ = 0;
};

// Reads a .fscan file (or an in-memory image of one) message by message. Errors (bad header, unknown
// version, bad magic, bad CRC, truncation, malformed payloads) are fs::Error "<path>: at byte N: ..." with
// the file offset. Reading allocates only at construction.
class ScanFileReader {
 public:
  explicit ScanFileReader(const std::filesystem::path& path, wire::FrameDecoder::Limits limits = {});
  // A file image in memory (not copied; must outlive the reader). `name` labels errors.
  ScanFileReader(std::span<const std::uint8_t> image, std::string name,
                 wire::FrameDecoder::Limits limits = {});
  ~ScanFileReader();
  ScanFileReader(const ScanFileReader&) = delete;
  ScanFileReader& operator=(const ScanFileReader&) = delete;

  // Next raw frame (payload valid until the next call). Returns false at a clean end of file.
  bool next_frame(wire::FrameView& frame);
  // Next decoded message. Returns false at a clean end of file.
  bool next(wire::DecodedMessage& out);

  std::uint16_t format_major() const { return major_; }
  std::uint16_t format_minor() const { return minor_; }
  std::uint64_t frames_read() const { return dec_.frames(); }
  const std::string& name() const { return name_; }

 private:
  void open_header();
  std::size_t read_chunk(std::span<std::uint8_t> dst);

  std::string name_;
  std::FILE* f_ = nullptr;
  std::span<const std::uint8_t> image_;
  std::size_t image_pos_ = 0;
  std::uint64_t file_pos_ = 0;
  std::vector<std::uint8_t> chunk_;
  std::span<const std::uint8_t> pending_;
  bool eof_ = false;
  std::uint16_t major_ = 0, minor_ = 0;
  wire::FrameDecoder dec_;
};

}  // namespace fs
