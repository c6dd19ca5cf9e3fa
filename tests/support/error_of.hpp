#pragma once
// Test helper: the message of the fs::Error that fn throws, or "<no error>" when it throws none (so that a
// check for a particular message fails loudly when nothing was thrown).
#include <functional>
#include <string>

#include "common/error.hpp"

namespace fs::test {

inline std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const fs::Error& e) {
    return e.what();
  }
  return "<no error>";
}

}  // namespace fs::test
