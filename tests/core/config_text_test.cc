// parse_config_text: what the loader reads a deployment file with.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "simgate/core/config.h"
#include "simgate/core/errors.h"

namespace simgate {
namespace {

using ::testing::HasSubstr;

std::string error_of(std::string_view text) {
  try {
    parse_config_text(text);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "accepted";
}

// nlohmann's parser ends a document at a NUL byte: `{...}\0<anything>` was accepted with
// the rest ignored (issue #17, item 9, a fuzz finding)
TEST(ConfigText, ANulByteIsRefusedWithItsPosition) {
  const std::string text("{\"a\": 1,\n \"b\": 2}\0{\"c\": 3}", 26);
  EXPECT_EQ(error_of(text),
            "configuration: expected a text file, found a NUL byte (line 2, column 9)");
  EXPECT_THAT(error_of(std::string("{\"a\": \"x\0y\"}", 12)),
              HasSubstr("a NUL byte (line 1, column 9)"));
  EXPECT_EQ(parse_config_text("{\"a\": 1,\n \"b\": 2}"), json({{"a", 1}, {"b", 2}}));
}

}  // namespace
}  // namespace simgate
