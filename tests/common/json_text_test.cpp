// parse_json_text (common/json_text.hpp): every way a JSON text can fail to parse is an fs::Error naming the
// source -- a syntax error with its byte offset, a number too large for a double (nlohmann::json's
// out_of_range, which escaped as a foreign exception before: the fw_config fuzz target found it). The readers
// of JSON files (firmware config, scene, match parameters, PFRG, calibration) all parse through it.
#include <gtest/gtest.h>

#include <string>

#include "common/json_text.hpp"
#include "support/error_of.hpp"

namespace fs {
namespace {

std::string error_of(const std::string& text) {
  return test::error_of([&] { parse_json_text(text, "cfg.json"); });
}

TEST(JsonText, ParsesAndNamesTheSourceOfEveryFailure) {
  EXPECT_EQ(parse_json_text(R"({"a": [1, 2.5e3]})", "x")["a"][1].get<double>(), 2500.0);
  const std::string syntax = error_of(R"({"a": 1,, })");
  EXPECT_NE(syntax.find("cfg.json"), std::string::npos) << syntax;
  EXPECT_NE(syntax.find("at byte 9"), std::string::npos) << syntax;  // nlohmann::json counts from 1
  for (const char* big : {R"({"period_us": 500e7777})", R"([1e400])", R"({"x": -1e99999})"}) {
    const std::string e = error_of(big);
    EXPECT_NE(e.find("cfg.json: invalid JSON"), std::string::npos) << big << ": " << e;
    EXPECT_NE(e.find("number overflow"), std::string::npos) << big << ": " << e;
  }
  EXPECT_NE(error_of("").find("cfg.json"), std::string::npos);
}

}  // namespace
}  // namespace fs
