#include "common/json_text.hpp"

#include "common/error.hpp"

namespace fs {

nlohmann::json parse_json_text(const std::string& text, const std::string& source) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw error_at_offset(source, e.byte, std::string("invalid JSON: ") + e.what());
  } catch (const nlohmann::json::exception& e) {
    throw Error(source + ": invalid JSON: " + e.what());
  }
}

}  // namespace fs
