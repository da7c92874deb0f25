// Bounded previews of client-supplied JSON values (describe_json, json_preview) and the
// nesting pre-scan (json_nests_deeper_than), core/include/simgate/core/config.h. Issue #17:
// an 80 000-deep value once overflowed the stack in the message that described it.
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "simgate/core/arguments.h"
#include "simgate/core/config.h"

namespace simgate {
namespace {

using ::testing::HasSubstr;

json nested_arrays(std::size_t depth) {
  json value = json::array();
  for (std::size_t i = 1; i < depth; ++i) {
    json outer = json::array();
    outer.push_back(std::move(value));
    value = std::move(outer);
  }
  return value;
}

json nested_objects(std::size_t depth) {
  json value = 1;
  for (std::size_t i = 0; i < depth; ++i) {
    json outer = json::object();
    outer["a"] = std::move(value);
    value = std::move(outer);
  }
  return value;
}

TEST(JsonPreviewTest, ShortValuesReadAsTheirCompactDump) {
  EXPECT_EQ(describe_json(json(nullptr)), "null");
  EXPECT_EQ(describe_json(json(true)), "boolean true");
  EXPECT_EQ(describe_json(json(3)), "number 3");
  EXPECT_EQ(describe_json(json(2.5)), "number 2.5");
  EXPECT_EQ(describe_json(json("abc")), "string \"abc\"");
  EXPECT_EQ(describe_json(json::parse(R"([1,"x",{"b":[true,null]}])")),
            R"(array [1,"x",{"b":[true,null]}])");
  EXPECT_EQ(describe_json(json::parse(R"({"a":1,"b":"q\"uote"})")),
            R"(object {"a":1,"b":"q\"uote"})");
  EXPECT_EQ(json_preview(json::array()), "[]");
  EXPECT_EQ(json_preview(json::object()), "{}");
}

TEST(JsonPreviewTest, LongValuesAreCutAt57CharactersAndEllipsis) {
  json many = json::array();
  for (int i = 0; i < 100; ++i) many.push_back(i);
  std::string full = many.dump();
  std::string preview = json_preview(many);
  EXPECT_EQ(preview, full.substr(0, 57) + "...");
  EXPECT_EQ(json_preview(json(std::string(61, 'x'))), "\"" + std::string(56, 'x') + "...");
  // exactly 60 characters: shown whole
  EXPECT_EQ(json_preview(json(std::string(58, 'x'))), "\"" + std::string(58, 'x') + "\"");
  // a multi-byte character is not split
  std::string accents;
  for (int i = 0; i < 40; ++i) accents += "\xc3\xa9";
  std::string cut = json_preview(json(accents));
  EXPECT_EQ(cut.substr(cut.size() - 3), "...");
  EXPECT_NO_THROW((void)json(cut).dump());  // valid UTF-8 (dump throws on invalid)
  EXPECT_LE(cut.size(), 60u);
}

TEST(JsonPreviewTest, AnEightyThousandDeepValueIsPreviewedShort) {
  for (const json& deep : {nested_arrays(80000), nested_objects(80000)}) {
    // before, the recursive dump behind it overflowed the stack
    std::string text = describe_json(deep);
    EXPECT_LT(text.size(), 100u) << text;
    EXPECT_THAT(text, HasSubstr("..."));
  }
  EXPECT_EQ(json_preview(nested_arrays(80000)), std::string(57, '[') + "...");
}

TEST(JsonPreviewTest, ATenMegabyteStringIsPreviewedShort) {
  json big(std::string(10 << 20, 'z'));
  std::string text = describe_json(big);
  EXPECT_LT(text.size(), 100u);
  EXPECT_EQ(text, "string \"" + std::string(56, 'z') + "...");
  // as an object key too
  json keyed = json::object();
  keyed[std::string(10 << 20, 'k')] = 1;
  text = describe_json(keyed);
  EXPECT_LT(text.size(), 100u);
}

TEST(JsonPreviewTest, TypeMismatchesOfDeepOrHugeArgumentsStayShort) {
  auto found = [](const json& j) -> std::string {
    try {
      (void)ArgTraits<std::string>::from_json(j);
    } catch (const TypeMismatch& m) {
      return m.found;
    }
    return "no mismatch";
  };
  EXPECT_LT(found(nested_arrays(80000)).size(), 100u);
  EXPECT_LT(found(nested_objects(80000)).size(), 100u);
  json many = json::array();
  for (int i = 0; i < 1000000; ++i) many.push_back(i);
  EXPECT_LT(found(many).size(), 100u);
}

TEST(JsonNestsDeeperThanTest, CountsBracketsOutsideStrings) {
  EXPECT_FALSE(json_nests_deeper_than("", 2));
  EXPECT_FALSE(json_nests_deeper_than("[[1]]", 2));
  EXPECT_TRUE(json_nests_deeper_than("[[[1]]]", 2));
  EXPECT_TRUE(json_nests_deeper_than(R"({"a":{"b":{}}})", 2));
  EXPECT_FALSE(json_nests_deeper_than(R"(["[[[[", "\"[[[["])", 1));
  EXPECT_FALSE(json_nests_deeper_than("[][][][]", 1));
  EXPECT_TRUE(json_nests_deeper_than(std::string(80000, '[') + std::string(80000, ']'), 128));
}

}  // namespace
}  // namespace simgate
