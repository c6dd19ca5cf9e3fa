#include "common/scan_file.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>

#include "common/byte_io.hpp"
#include "common/input_file.hpp"

namespace fs {

void encode_scan_file_header(std::span<std::uint8_t, kScanFileHeaderSize> out) {
  ByteWriter w(out);
  w.put_bytes(kScanFileMagic);
  w.put<std::uint16_t>(kScanFileMajor);
  w.put<std::uint16_t>(kScanFileMinor);
  w.put<std::uint32_t>(static_cast<std::uint32_t>(kScanFileHeaderSize));
}

std::uint32_t parse_scan_file_header(std::span<const std::uint8_t> b, const std::string& source) {
  if (b.size() < kScanFileHeaderSize)
    throw error_at_offset(source, b.size(),
                          "truncated .fscan file header: " + std::to_string(b.size()) + " of " +
                              std::to_string(kScanFileHeaderSize) + " bytes");
  for (std::size_t i = 0; i < kScanFileMagic.size(); ++i)
    if (b[i] != kScanFileMagic[i])
      throw error_at_offset(source, i, "not a .fscan file (bad file magic, expected \"FSCAN\\r\\n\\x1a\")");
  const auto major = load_le<std::uint16_t>(b.data() + 8);
  const auto minor = load_le<std::uint16_t>(b.data() + 10);
  if (major != kScanFileMajor)
    throw error_at_offset(source, 8,
                          "unsupported .fscan format version " + std::to_string(major) + "." +
                              std::to_string(minor) + " (this reader reads major version " +
                              std::to_string(kScanFileMajor) + ")");
  const auto size = load_le<std::uint32_t>(b.data() + 12);
  if (size < kScanFileHeaderSize || size > kScanFileMaxHeaderSize)
    throw error_at_offset(source, 12,
                          "bad .fscan header size " + std::to_string(size) + " (expected " +
                              std::to_string(kScanFileHeaderSize) + ".." +
                              std::to_string(kScanFileMaxHeaderSize) + ")");
  return size;
}

// ---- writer
// -------------------------------------------------------------------------------------------------

ScanFileWriter::ScanFileWriter(const std::filesystem::path& path) : path_(path) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) throw Error(path.string() + ": cannot create .fscan file: " + std::strerror(errno));
  std::array<std::uint8_t, kScanFileHeaderSize> h{};
  encode_scan_file_header(h);
  write(h);
}

ScanFileWriter::~ScanFileWriter() {
  if (f_) std::fclose(f_);
}

void ScanFileWriter::write(std::span<const std::uint8_t> bytes) {
  if (!f_) throw Error(path_.string() + ": write after close");
  if (bytes.empty()) return;
  if (std::fwrite(bytes.data(), 1, bytes.size(), f_) != bytes.size())
    throw error_at_offset(path_.string(), written_, std::string("write failed: ") + std::strerror(errno));
  written_ += bytes.size();
}

void ScanFileWriter::flush() {
  if (f_ && std::fflush(f_) != 0)
    throw error_at_offset(path_.string(), written_, std::string("flush failed: ") + std::strerror(errno));
}

void ScanFileWriter::close() {
  if (!f_) return;
  std::FILE* f = f_;
  f_ = nullptr;
  if (std::fclose(f) != 0)
    throw error_at_offset(path_.string(), written_, std::string("close failed: ") + std::strerror(errno));
}

// ---- reader
// -------------------------------------------------------------------------------------------------

namespace {
constexpr std::size_t kChunk = 64 * 1024;
}

ScanFileReader::ScanFileReader(const std::filesystem::path& path, wire::FrameDecoder::Limits limits)
    : name_(path.string()), chunk_(kChunk), dec_(name_, limits) {
  // A device or FIFO is refused (no size cap here: the scan limits bound what is kept of a file).
  std::uint64_t size = 0;
  const int fd = open_input_file(path, UINT64_MAX, ".fscan file", size);
  f_ = ::fdopen(fd, "rb");
  if (!f_) {
    const int e = errno;
    ::close(fd);
    throw Error(name_ + ": cannot open .fscan file: " + std::strerror(e));
  }
  try {
    open_header();
  } catch (...) {
    std::fclose(f_);
    f_ = nullptr;
    throw;
  }
}

ScanFileReader::ScanFileReader(std::span<const std::uint8_t> image, std::string name,
                               wire::FrameDecoder::Limits limits)
    : name_(std::move(name)), image_(image), dec_(name_, limits) {
  open_header();
}

ScanFileReader::~ScanFileReader() {
  if (f_) std::fclose(f_);
}

std::size_t ScanFileReader::read_chunk(std::span<std::uint8_t> dst) {
  if (f_) {
    const std::size_t n = std::fread(dst.data(), 1, dst.size(), f_);
    if (n < dst.size() && std::ferror(f_))
      throw error_at_offset(name_, file_pos_ + n, std::string("read failed: ") + std::strerror(errno));
    file_pos_ += n;
    return n;
  }
  const std::size_t n = std::min(dst.size(), image_.size() - image_pos_);
  if (n > 0) std::memcpy(dst.data(), image_.data() + image_pos_, n);
  image_pos_ += n;
  file_pos_ += n;
  return n;
}

void ScanFileReader::open_header() {
  std::array<std::uint8_t, kScanFileHeaderSize> h{};
  const std::size_t n = read_chunk(h);
  const std::uint32_t size = parse_scan_file_header(std::span<const std::uint8_t>(h.data(), n), name_);
  major_ = load_le<std::uint16_t>(h.data() + 8);
  minor_ = load_le<std::uint16_t>(h.data() + 10);
  // Skip header fields of a newer minor version.
  std::size_t skip = size - kScanFileHeaderSize;
  std::array<std::uint8_t, 256> scratch{};
  while (skip > 0) {
    const std::size_t k = read_chunk(std::span<std::uint8_t>(scratch.data(), std::min(skip, scratch.size())));
    if (k == 0)
      throw error_at_offset(name_, file_pos_,
                            "truncated .fscan file header (header size " + std::to_string(size) + ")");
    skip -= k;
  }
  dec_.reset(size);
}

bool ScanFileReader::next_frame(wire::FrameView& frame) {
  for (;;) {
    if (dec_.next(frame)) return true;
    if (!pending_.empty()) {
      pending_ = pending_.subspan(dec_.feed(pending_));
      continue;
    }
    if (eof_) {
      dec_.finish();
      return false;
    }
    if (f_) {
      const std::size_t n = read_chunk(chunk_);
      pending_ = std::span<const std::uint8_t>(chunk_.data(), n);
      if (n == 0) eof_ = true;
    } else {
      pending_ = image_.subspan(image_pos_);
      image_pos_ = image_.size();
      eof_ = true;
    }
  }
}

bool ScanFileReader::next(wire::DecodedMessage& out) {
  wire::FrameView f;
  if (!next_frame(f)) return false;
  wire::decode(f, out, name_);
  return true;
}

}  // namespace fs
