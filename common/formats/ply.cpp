#include "common/formats/ply.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <stdexcept>

namespace fs::formats {

std::optional<PlyType> ply_type(std::string_view s) {
  struct Entry {
    std::string_view a, b;
    PlyType t;
  };
  static constexpr Entry table[] = {{"char", "int8", PlyType::I8},      {"uchar", "uint8", PlyType::U8},
                                    {"short", "int16", PlyType::I16},   {"ushort", "uint16", PlyType::U16},
                                    {"int", "int32", PlyType::I32},     {"uint", "uint32", PlyType::U32},
                                    {"float", "float32", PlyType::F32}, {"double", "float64", PlyType::F64}};
  for (const auto& e : table)
    if (s == e.a || s == e.b) return e.t;
  return std::nullopt;
}

std::size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::I8:
    case PlyType::U8:
      return 1;
    case PlyType::I16:
    case PlyType::U16:
      return 2;
    case PlyType::I32:
    case PlyType::U32:
    case PlyType::F32:
      return 4;
    case PlyType::F64:
      return 8;
  }
  return 1;
}

namespace {

template <typename T>
T load(const char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

}  // namespace

double ply_decode(const char* p, PlyType t, bool swap) {
  switch (t) {
    case PlyType::I8:
      return load<std::int8_t>(p, swap);
    case PlyType::U8:
      return load<std::uint8_t>(p, swap);
    case PlyType::I16:
      return load<std::int16_t>(p, swap);
    case PlyType::U16:
      return load<std::uint16_t>(p, swap);
    case PlyType::I32:
      return load<std::int32_t>(p, swap);
    case PlyType::U32:
      return load<std::uint32_t>(p, swap);
    case PlyType::F32:
      return static_cast<double>(load<float>(p, swap));
    case PlyType::F64:
      return load<double>(p, swap);
  }
  return 0.0;
}

std::uint64_t ply_min_instance_bytes(const PlyElement& e, PlyFormat format) {
  std::uint64_t n = 0;
  for (const auto& p : e.props)
    n += format == PlyFormat::Ascii ? 2 : ply_size(p.is_list ? p.count_type : p.type);
  return n;
}

PlyHeader parse_ply_header(std::string_view bytes, const std::string& file, const PlyHeaderRules& rules) {
  TextLines in(bytes, file, rules.style);
  const auto fail = [&](PlyIssue issue, std::string_view token = {}) {
    rules.fail(issue, in, token);
    throw std::logic_error("PlyHeaderRules::fail returned");
  };
  if (rules.style == TextStyle::Header) {
    if (!in.next() || in.line() != "ply") fail(PlyIssue::NoMagic);
  } else {
    if (!in.next() || in.tokens().size() != 1 || in.tokens()[0] != "ply") fail(PlyIssue::NoMagic);
  }
  PlyHeader h;
  bool have_format = false, have_end = false;
  while (in.next()) {
    const auto& t = in.tokens();
    if (t.empty()) continue;
    const std::string_view key = t[0];
    if (key == "comment" || key == "obj_info") {
      if (rules.on_info) rules.on_info(in);
    } else if (key == "end_header") {
      have_end = true;
      break;
    } else if (key == "format") {
      if (t.size() != 3) fail(PlyIssue::FormatLine);
      if (t[1] == "ascii")
        h.format = PlyFormat::Ascii;
      else if (t[1] == "binary_little_endian")
        h.format = PlyFormat::BinaryLE;
      else if (t[1] == "binary_big_endian")
        h.format = PlyFormat::BinaryBE;
      else
        fail(PlyIssue::UnknownFormat, t[1]);
      if (rules.require_version_1_0 && t[2] != "1.0") fail(PlyIssue::UnsupportedVersion, t[2]);
      have_format = true;
    } else if (key == "element") {
      if (t.size() != 3) fail(PlyIssue::ElementLine);
      if (h.elements.size() >= rules.max_elements) fail(PlyIssue::TooManyElements);
      std::uint64_t count = 0;
      if (rules.signed_counts) {
        std::int64_t n = 0;
        if (!parse_i64(t[2], n) || n < 0) fail(PlyIssue::BadElementCount, t[2]);
        count = static_cast<std::uint64_t>(n);
      } else if (!parse_u64(t[2], count) || count > rules.max_count) {
        fail(PlyIssue::BadElementCount, t[2]);
      }
      h.elements.push_back(PlyElement{std::string(t[1]), count, {}});
    } else if (key == "property") {
      if (h.elements.empty()) fail(PlyIssue::PropertyBeforeElement);
      auto& props = h.elements.back().props;
      if (props.size() >= rules.max_properties) fail(PlyIssue::TooManyProperties);
      PlyProperty p;
      if (t.size() == 5 && t[1] == "list") {
        const auto ct = ply_type(t[2]);
        if (!ct || !ply_is_integer(*ct)) fail(PlyIssue::BadListCountType, t[2]);
        const auto it = ply_type(t[3]);
        if (!it) fail(PlyIssue::UnknownPropertyType, t[3]);
        p.is_list = true;
        p.count_type = *ct;
        p.type = *it;
        p.name = std::string(t[4]);
      } else if (t.size() == 3) {
        const auto it = ply_type(t[1]);
        if (!it) fail(PlyIssue::UnknownPropertyType, t[1]);
        p.type = *it;
        p.name = std::string(t[2]);
      } else {
        fail(PlyIssue::PropertyLine);
      }
      props.push_back(std::move(p));
    } else {
      fail(PlyIssue::UnknownKeyword, key);
    }
  }
  if (!have_end) fail(PlyIssue::NoEndHeader);
  if (!have_format) fail(PlyIssue::NoFormat);
  h.body_offset = in.offset();
  h.end_offset = in.offset();
  h.body_line = in.number() + 1;
  return h;
}

PlyBody::Status PlyBody::read(PlyType t, double& out, bool integer_syntax) {
  if (format_ == PlyFormat::Ascii) {
    if (!tokens_.next(token_)) return Status::End;
    if (integer_syntax) {
      const auto v = to_int(token_);
      if (!v) return Status::BadNumber;
      out = static_cast<double>(*v);
      return Status::Ok;
    }
    return parse_double(token_, out) ? Status::Ok : Status::BadNumber;
  }
  const std::size_t n = ply_size(t);
  if (bytes_.size() - pos_ < n) return Status::End;
  const bool swap = (format_ == PlyFormat::BinaryBE) == (std::endian::native == std::endian::little);
  out = ply_decode(bytes_.data() + pos_, t, swap);
  pos_ += n;
  return Status::Ok;
}

}  // namespace fs::formats
