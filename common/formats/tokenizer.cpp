#include "common/formats/tokenizer.hpp"

#include <cctype>
#include <charconv>
#include <cmath>

#include "common/error.hpp"

namespace fs::formats {

bool TextLines::next(std::size_t max_line) {
  if (pos_ >= data_.size()) return false;
  line_offset_ = pos_;
  ++number_;
  const char* base = data_.data();
  std::size_t end = pos_;
  if (style_ == TextStyle::Loose) {
    const std::size_t nl = data_.find('\n', pos_);
    end = nl == std::string_view::npos ? data_.size() : nl;
  } else {
    while (end < data_.size() && base[end] != '\n') {
      if (end - pos_ >= max_line)
        throw error_at_offset(file_, pos_, "header line longer than " + std::to_string(max_line) + " bytes");
      if (base[end] == '\0') throw error_at_offset(file_, end, "NUL byte in text header");
      ++end;
    }
  }
  std::size_t len = end - pos_;
  if (style_ == TextStyle::Header && len > 0 && base[pos_ + len - 1] == '\r') --len;
  line_ = std::string_view(base + pos_, len);
  pos_ = end < data_.size() ? end + 1 : end;
  tokens_.clear();
  if (style_ == TextStyle::Loose) {
    std::size_t i = 0;
    const char comment = comment_;
    while (i < line_.size()) {
      while (i < line_.size() && is_space(line_[i])) ++i;
      if (i >= line_.size() || (comment != 0 && line_[i] == comment)) break;
      const std::size_t start = i;
      while (i < line_.size() && !is_space(line_[i]) && !(comment != 0 && line_[i] == comment)) ++i;
      tokens_.push_back(line_.substr(start, i - start));
    }
    return true;
  }
  std::size_t i = 0;
  while (i < line_.size()) {
    while (i < line_.size() && (line_[i] == ' ' || line_[i] == '\t')) ++i;
    std::size_t j = i;
    while (j < line_.size() && line_[j] != ' ' && line_[j] != '\t') ++j;
    if (j > i) tokens_.push_back(line_.substr(i, j - i));
    i = j;
  }
  return true;
}

void TextLines::fail(const std::string& what) const { throw error_at_offset(file_, line_offset_, what); }

std::uint64_t TextLines::as_u64(std::size_t i, std::uint64_t max_value) const {
  const std::string key = tokens_.empty() ? std::string() : std::string(tokens_[0]);
  if (i >= tokens_.size()) fail(key + ": missing value");
  std::uint64_t v = 0;
  if (!parse_u64(tokens_[i], v))
    fail(key + ": '" + std::string(tokens_[i]) + "' is not a non-negative integer");
  if (v > max_value) fail(key + ": " + std::to_string(v) + " exceeds the limit " + std::to_string(max_value));
  return v;
}

double TextLines::as_finite_double(std::size_t i) const {
  const std::string key = tokens_.empty() ? std::string() : std::string(tokens_[0]);
  if (i >= tokens_.size()) fail(key + ": missing value");
  double v = 0;
  if (!parse_double(tokens_[i], v)) fail(key + ": '" + std::string(tokens_[i]) + "' is not a number");
  if (!std::isfinite(v)) fail(key + ": value '" + std::string(tokens_[i]) + "' is not finite");
  return v;
}

bool parse_double(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_u64(std::string_view s, std::uint64_t& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_i64(std::string_view s, std::int64_t& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string quote(std::string_view tok) {
  std::string t(tok.substr(0, 40));
  for (char& c : t)
    if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
  return "'" + t + (tok.size() > 40 ? "...'" : "'");
}

}  // namespace fs::formats
