#pragma once
// The one exception type for bad input and failed operations. Messages name the file, field or byte offset.
#include <cstdint>
#include <stdexcept>
#include <string>

namespace fs {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// "file: at byte 1234: what"
inline Error error_at_offset(const std::string& file, std::uint64_t offset, const std::string& what) {
  return Error(file + ": at byte " + std::to_string(offset) + ": " + what);
}
// "file:12: what"
inline Error error_at_line(const std::string& file, std::uint64_t line, const std::string& what) {
  return Error(file + ":" + std::to_string(line) + ": " + what);
}

}  // namespace fs
