#pragma once
// PLY 1.0, the one place that knows the format: the header (format, elements, scalar and list properties,
// comment / obj_info lines) and the element bodies in ascii, binary_little_endian and binary_big_endian. The
// mesh reader (common/formats/ply_mesh.cpp: vertex + face) and the point-cloud reader
// (host/io/ply_reader.cpp: vertex + organized grid) both sit on it and word their own errors: the parser
// reports what is wrong (PlyIssue, PlyBody::Status) with the line and byte offset, the reader throws.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/formats/tokenizer.hpp"

namespace fs::formats {

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };
enum class PlyType : std::uint8_t { I8, U8, I16, U16, I32, U32, F32, F64 };

// "char" / "int8", "uchar" / "uint8", ... "double" / "float64"; nullopt for anything else.
std::optional<PlyType> ply_type(std::string_view name);
std::size_t ply_size(PlyType t);
inline bool ply_is_integer(PlyType t) { return t != PlyType::F32 && t != PlyType::F64; }

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::U8;
  PlyType type = PlyType::F32;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
};

// What is wrong with a header; the reader's PlyHeaderRules::fail words it.
enum class PlyIssue {
  NoMagic,                // first line is not "ply"
  FormatLine,             // format line without exactly 2 values
  UnknownFormat,          // token = the format
  UnsupportedVersion,     // token = the version (only with require_version_1_0)
  TooManyElements,        // more than max_elements
  ElementLine,            // element line without a name and a count
  BadElementCount,        // token = the count
  TooManyProperties,      // more than max_properties in one element
  PropertyBeforeElement,  //
  BadListCountType,       // token = the type (unknown or not an integer type)
  UnknownPropertyType,    // token = the type
  PropertyLine,           // property line of neither shape
  UnknownKeyword,         // token = the keyword
  NoEndHeader,            // data ends inside the header
  NoFormat,               // header without a format line
};

struct PlyHeaderRules {
  // Header: the cloud reader's (magic line exactly "ply", lines of at most 4096 bytes without NUL bytes,
  // split at ' ' '\t'); Loose: the mesh reader's (magic = the only token of line 1, split at any ASCII
  // space).
  TextStyle style = TextStyle::Header;
  bool require_version_1_0 = false;
  // Element counts: non-negative integers (parse_u64) up to max_count; with signed_counts, integers
  // (parse_i64) that are >= 0.
  bool signed_counts = false;
  std::uint64_t max_count = UINT64_MAX;
  std::size_t max_elements = SIZE_MAX;
  std::size_t max_properties = SIZE_MAX;
  // Called for each comment and obj_info line, in header order (may throw).
  std::function<void(const TextLines&)> on_info;
  // Throws the reader's fs::Error for `issue` found on the current line of `lines` (token: the value at
  // fault, if any). Must not return.
  std::function<void(PlyIssue, const TextLines&, std::string_view token)> fail;
};

struct PlyHeader {
  PlyFormat format = PlyFormat::Ascii;
  std::vector<PlyElement> elements;
  std::size_t body_offset = 0;   // byte offset of the first body byte
  std::uint64_t body_line = 0;   // line number of the first body byte
  std::uint64_t end_offset = 0;  // byte offset just past end_header
};

// The fewest bytes one instance of `e` takes in the body: binary, the sizes of its scalars and of its lists'
// counts (empty lists); ascii, 2 per property (a digit and a separator). Readers check the declared counts
// against the body with it before allocating anything for them.
std::uint64_t ply_min_instance_bytes(const PlyElement& e, PlyFormat format);

PlyHeader parse_ply_header(std::string_view bytes, const std::string& file, const PlyHeaderRules& rules);

// Reads scalars from an element body in order: binary by bytes (either byte order), ascii by tokens. Never
// throws: the reader words the errors from the status and the positions.
class PlyBody {
 public:
  enum class Status { Ok, End, BadNumber };

  PlyBody(std::string_view bytes, const PlyHeader& header, TextStyle style)
      : bytes_(bytes),
        format_(header.format),
        pos_(header.body_offset),
        tokens_(bytes.substr(header.body_offset), header.body_offset, header.body_line, style) {}

  // The next value as a double. Ascii: with integer_syntax the token must be an integer ("1.0" is
  // BadNumber), otherwise any number (nan and inf included).
  Status read(PlyType t, double& out, bool integer_syntax = false);

  bool binary() const { return format_ != PlyFormat::Ascii; }
  // Byte offset of the cursor (just past the last value read).
  std::size_t offset() const { return binary() ? pos_ : tokens_.offset(); }
  // Bytes after the cursor.
  std::size_t remaining() const { return bytes_.size() - offset(); }
  // Ascii: the last token read (also after BadNumber), its byte offset, the line of the cursor.
  std::string_view token() const { return token_; }
  std::size_t token_offset() const { return tokens_.token_offset(); }
  std::uint64_t line() const { return tokens_.line(); }

 private:
  std::string_view bytes_;
  PlyFormat format_;
  std::size_t pos_;
  TextTokens tokens_;
  std::string_view token_;
};

// Decodes one binary scalar (swap: the data's byte order differs from the host's).
double ply_decode(const char* p, PlyType t, bool swap);

}  // namespace fs::formats
