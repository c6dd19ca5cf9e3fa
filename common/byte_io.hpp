#pragma once
// Little-endian field-by-field encoding into / decoding from byte spans. Bounds are checked on every access:
// ByteWriter throws fs::Error when the destination is too small, ByteReader when the source is too short
// (both name the field and the byte offset). No allocation, no struct memcpy.
#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>

#include "common/error.hpp"

namespace fs {

static_assert(std::endian::native == std::endian::little || std::endian::native == std::endian::big);

namespace detail {
template <class U>
constexpr U byteswap_if_big(U v) {
  if constexpr (std::endian::native == std::endian::big && sizeof(U) > 1) {
    U r = 0;
    for (std::size_t i = 0; i < sizeof(U); ++i) r = static_cast<U>((r << 8) | ((v >> (8 * i)) & 0xFF));
    return r;
  } else {
    return v;
  }
}
template <std::size_t N>
struct uint_of;
template <>
struct uint_of<1> {
  using type = std::uint8_t;
};
template <>
struct uint_of<2> {
  using type = std::uint16_t;
};
template <>
struct uint_of<4> {
  using type = std::uint32_t;
};
template <>
struct uint_of<8> {
  using type = std::uint64_t;
};
}  // namespace detail

// Store / load one arithmetic value little-endian at p (no bounds check; the classes below check).
template <class T>
inline void store_le(std::uint8_t* p, T v) {
  static_assert(std::is_arithmetic_v<T> || std::is_enum_v<T>);
  using U = typename detail::uint_of<sizeof(T)>::type;
  U u;
  if constexpr (std::is_enum_v<T>)
    u = static_cast<U>(v);
  else
    u = std::bit_cast<U>(v);
  u = detail::byteswap_if_big(u);
  std::memcpy(p, &u, sizeof(U));
}
template <class T>
inline T load_le(const std::uint8_t* p) {
  static_assert(std::is_arithmetic_v<T>);
  using U = typename detail::uint_of<sizeof(T)>::type;
  U u;
  std::memcpy(&u, p, sizeof(U));
  return std::bit_cast<T>(detail::byteswap_if_big(u));
}

class ByteWriter {
 public:
  explicit ByteWriter(std::span<std::uint8_t> out) : out_(out) {}

  template <class T>
  void put(T v) {
    need(sizeof(T));
    store_le<T>(out_.data() + pos_, v);
    pos_ += sizeof(T);
  }
  void put_bytes(std::span<const std::uint8_t> b) {
    need(b.size());
    if (!b.empty()) std::memcpy(out_.data() + pos_, b.data(), b.size());
    pos_ += b.size();
  }
  // u16 length + bytes; throws when longer than max_len.
  void put_string(std::string_view s, std::size_t max_len, const char* field) {
    if (s.size() > max_len || s.size() > 0xFFFF)
      throw Error(std::string("encode: field ") + field + " is " + std::to_string(s.size()) +
                  " bytes, maximum " + std::to_string(max_len));
    put<std::uint16_t>(static_cast<std::uint16_t>(s.size()));
    put_bytes({reinterpret_cast<const std::uint8_t*>(s.data()), s.size()});
  }
  std::size_t position() const { return pos_; }
  std::span<std::uint8_t> written() const { return out_.first(pos_); }
  std::span<std::uint8_t> rest() const { return out_.subspan(pos_); }
  void skip(std::size_t n) {
    need(n);
    pos_ += n;
  }

 private:
  void need(std::size_t n) const {
    if (out_.size() - pos_ < n)
      throw Error("encode: output buffer of " + std::to_string(out_.size()) + " bytes too small at byte " +
                  std::to_string(pos_) + " (need " + std::to_string(n) + " more)");
  }
  std::span<std::uint8_t> out_;
  std::size_t pos_ = 0;
};

// Reads fields from a span. Errors are reported as "<source>: at byte <base + position>: <field>: ...".
class ByteReader {
 public:
  ByteReader(std::span<const std::uint8_t> in, const std::string* source = nullptr, std::uint64_t base = 0)
      : in_(in), source_(source), base_(base) {}

  template <class T>
  T get(const char* field) {
    need(sizeof(T), field);
    T v = load_le<T>(in_.data() + pos_);
    pos_ += sizeof(T);
    return v;
  }
  std::span<const std::uint8_t> get_bytes(std::size_t n, const char* field) {
    need(n, field);
    auto s = in_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  // u16 length + bytes, into `out` (assign: reuses out's capacity, so a reserved string never allocates).
  void get_string(std::string& out, std::size_t max_len, const char* field) {
    const std::uint64_t at = offset();
    const std::uint16_t n = get<std::uint16_t>(field);
    if (n > max_len)
      throw fail_at(at, std::string(field) + ": length " + std::to_string(n) + " exceeds maximum " +
                            std::to_string(max_len));
    auto b = get_bytes(n, field);
    out.assign(reinterpret_cast<const char*>(b.data()), b.size());
  }
  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return in_.size() - pos_; }
  std::uint64_t offset() const { return base_ + pos_; }  // absolute offset of the next byte
  Error fail(const std::string& what) const { return fail_at(offset(), what); }
  Error fail_at(std::uint64_t at, const std::string& what) const {
    return error_at_offset(source_ ? *source_ : std::string("buffer"), at, what);
  }

 private:
  void need(std::size_t n, const char* field) const {
    if (in_.size() - pos_ < n)
      throw fail(std::string("truncated payload: field ") + field + " needs " + std::to_string(n) +
                 " bytes, only " + std::to_string(in_.size() - pos_) + " left");
  }
  std::span<const std::uint8_t> in_;
  const std::string* source_;
  std::uint64_t base_;
  std::size_t pos_ = 0;
};

}  // namespace fs
