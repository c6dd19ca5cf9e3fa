#pragma once
// Line/token scanner for the text headers of PCD and PLY files: yields one line at a time with its byte
// offset, split into whitespace-separated tokens, and parses numbers strictly (whole token, finite).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fs::host::io_detail {

class HeaderLines {
 public:
  HeaderLines(std::span<const std::byte> data, std::string file) : data_(data), file_(std::move(file)) {}

  // Next line (without the line break; a trailing '\r' is dropped). Returns false at end of data.
  // max_line bounds a header line so binary garbage cannot make us scan megabytes as a "line".
  bool next(std::size_t max_line = 4096);
  std::uint64_t line_offset() const { return line_offset_; }  // byte offset of the current line
  std::uint64_t offset() const { return pos_; }               // byte offset just past the current line
  std::string_view line() const { return line_; }
  const std::vector<std::string_view>& tokens() const { return tokens_; }
  const std::string& file() const { return file_; }
  void seek(std::size_t pos) { pos_ = pos; }

  // Token i parsed as a number; throws fs::Error naming the file, offset and key on failure.
  std::uint64_t as_u64(std::size_t i, std::uint64_t max_value) const;
  double as_finite_double(std::size_t i) const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  std::span<const std::byte> data_;
  std::string file_;
  std::size_t pos_ = 0;
  std::uint64_t line_offset_ = 0;
  std::string_view line_;
  std::vector<std::string_view> tokens_;
};

// Strict whole-token number parsing (std::from_chars; accepts nan/inf for doubles).
bool parse_double(std::string_view s, double& out);
bool parse_u64(std::string_view s, std::uint64_t& out);
bool parse_i64(std::string_view s, std::int64_t& out);

}  // namespace fs::host::io_detail
