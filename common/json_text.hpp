#pragma once
// Parsing a JSON document that came from a file or the command line (external input): every failure becomes
// an fs::Error naming the source -- a syntax error with its byte offset, and the parser's other errors too
// (nlohmann::json throws out_of_range for a number that overflows, e.g. 500e7777: without this it would
// escape as a foreign exception; the fw_config fuzz target covers it).
#include <string>

#include <nlohmann/json.hpp>

namespace fs {

nlohmann::json parse_json_text(const std::string& text, const std::string& source);

}  // namespace fs
