#pragma once
// The text tokenizer of every file reader (mesh formats, PLY, PCD): lines with their number and byte offset
// split into whitespace-separated tokens (TextLines), a token stream over a whole text (TextTokens, for ASCII
// STL and ASCII PLY bodies), and strict whole-token number parsing.
//
// Two whitespace styles, because the readers built on them accept slightly different text:
//  * Header (PCD and PLY cloud headers): a line loses one trailing '\r' and splits at ' ' and '\t'; a NUL
//  byte
//    or a line longer than next()'s bound is an fs::Error naming the byte offset. Tokens of a body split at
//    ' ', '\t', '\r' and '\n'.
//  * Loose (OFF, OBJ, STL and PLY meshes): tokens split at any of ' ' '\t' '\r' '\f' '\v' (and '\n'); a line
//    ends at the comment character when there is one; no length bound.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fs::formats {

enum class TextStyle { Header, Loose };

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }
inline bool is_separator(char c, TextStyle style) {
  return style == TextStyle::Loose ? is_space(c) || c == '\n'
                                   : c == ' ' || c == '\t' || c == '\n' || c == '\r';
}

class TextLines {
 public:
  TextLines(std::span<const std::byte> data, std::string file, TextStyle style = TextStyle::Header,
            char comment = 0)
      : data_(reinterpret_cast<const char*>(data.data()), data.size()),
        file_(std::move(file)),
        style_(style),
        comment_(comment) {}
  TextLines(std::string_view text, std::string file, TextStyle style = TextStyle::Header, char comment = 0)
      : data_(text), file_(std::move(file)), style_(style), comment_(comment) {}

  // Next line (without the line break) and its tokens. Returns false at end of data. Header style: max_line
  // bounds a line so binary garbage cannot make us scan megabytes as a "line".
  bool next(std::size_t max_line = 4096);
  std::uint64_t number() const { return number_; }            // 1-based number of the current line
  std::uint64_t line_offset() const { return line_offset_; }  // byte offset of the current line
  std::uint64_t offset() const { return pos_; }               // byte offset just past the current line
  std::string_view line() const { return line_; }
  const std::vector<std::string_view>& tokens() const { return tokens_; }
  const std::string& file() const { return file_; }
  void seek(std::size_t pos) { pos_ = pos; }

  // Token i parsed as a number; throws fs::Error naming the file, offset and key on failure.
  std::uint64_t as_u64(std::size_t i, std::uint64_t max_value) const;
  double as_finite_double(std::size_t i) const;
  // fs::Error "file: at byte <line offset>: what".
  [[noreturn]] void fail(const std::string& what) const;

 private:
  std::string_view data_;
  std::string file_;
  TextStyle style_;
  char comment_;
  std::size_t pos_ = 0;
  std::uint64_t number_ = 0;
  std::uint64_t line_offset_ = 0;
  std::string_view line_;
  std::vector<std::string_view> tokens_;
};

// Tokens of a whole text, across lines, with the line number and byte offset of each.
class TextTokens {
 public:
  // `base` is the byte offset of text[0] in the file, `first_line` its line number.
  TextTokens(std::string_view text, std::size_t base, std::uint64_t first_line, TextStyle style)
      : text_(text), base_(base), line_(first_line), style_(style) {}
  bool next(std::string_view& tok) {
    while (pos_ < text_.size() && is_separator(text_[pos_], style_)) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ >= text_.size()) return false;
    token_at_ = pos_;
    while (pos_ < text_.size() && !is_separator(text_[pos_], style_)) ++pos_;
    tok = text_.substr(token_at_, pos_ - token_at_);
    return true;
  }
  std::uint64_t line() const { return line_; }                    // line of the last token (or of the end)
  std::size_t offset() const { return base_ + pos_; }             // byte offset just past the last token
  std::size_t token_offset() const { return base_ + token_at_; }  // byte offset of the last token
  std::size_t remaining() const { return text_.size() - pos_; }   // bytes after the last token
  std::size_t local_position() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t base_;
  std::size_t pos_ = 0;
  std::size_t token_at_ = 0;
  std::uint64_t line_;
  TextStyle style_;
};

// Strict whole-token number parsing (std::from_chars, a leading '+' allowed; accepts nan/inf for doubles).
bool parse_double(std::string_view s, double& out);
bool parse_u64(std::string_view s, std::uint64_t& out);
bool parse_i64(std::string_view s, std::int64_t& out);
inline std::optional<double> to_double(std::string_view s) {
  double v = 0;
  if (!parse_double(s, v)) return std::nullopt;
  return v;
}
inline std::optional<long long> to_int(std::string_view s) {
  std::int64_t v = 0;
  if (!parse_i64(s, v)) return std::nullopt;
  return static_cast<long long>(v);
}

// Lower-case copy (ASCII).
std::string lower(std::string_view s);
// 'tok' for error messages: at most 40 characters, non-printable ones as '?'.
std::string quote(std::string_view tok);

}  // namespace fs::formats
