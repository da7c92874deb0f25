// The socket transport's parameters parser: Python literals and JSON, never evaluated.
#include "simgate/morse/params_parser.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

namespace simgate::socket {
namespace {

using ::testing::HasSubstr;

json ok(std::string_view text) {
  ParamsParse p = parse_params(text);
  EXPECT_TRUE(p.ok) << "'" << text << "': " << p.error << " at column " << p.column;
  return p.value;
}

ParamsParse bad(std::string_view text) {
  ParamsParse p = parse_params(text);
  EXPECT_FALSE(p.ok) << "'" << text << "' parsed as " << p.value.dump();
  return p;
}

TEST(SocketParamsParser, EmptyTextMeansNoArguments) {
  EXPECT_TRUE(ok("").is_null());
  EXPECT_TRUE(ok("  \t ").is_null());
}

TEST(SocketParamsParser, PythonTuplesAndListsBecomeArrays) {
  EXPECT_EQ(ok("(1,2)"), json::parse("[1,2]"));
  EXPECT_EQ(ok("(5,)"), json::parse("[5]"));
  EXPECT_EQ(ok("(5)"), json::parse("[5]"));  // parentheses always make a tuple
  EXPECT_EQ(ok("()"), json::array());
  EXPECT_EQ(ok("[]"), json::array());
  EXPECT_EQ(ok("[1.0, 1.6]"), json::parse("[1.0, 1.6]"));
  EXPECT_EQ(ok("[1, 2,]"), json::parse("[1,2]"));
  EXPECT_EQ(ok(" ( ( 1 , ) , [ ] ) "), json::parse("[[1],[]]"));
}

TEST(SocketParamsParser, PythonAndJsonConstants) {
  EXPECT_EQ(ok("(True, False, None)"), json::parse("[true,false,null]"));
  EXPECT_EQ(ok("[true, false, null]"), json::parse("[true,false,null]"));
  json special = ok("[NaN, Infinity, -Infinity]");
  EXPECT_TRUE(std::isnan(special[0].get<double>()));
  EXPECT_EQ(special[1].get<double>(), INFINITY);
  EXPECT_EQ(special[2].get<double>(), -INFINITY);
}

TEST(SocketParamsParser, Numbers) {
  json n =
      ok("(0, -7, +3, 1.5, .5, 2., 1e3, -2.5E-2, 9223372036854775807, 18446744073709551615, "
         "-9223372036854775808)");
  EXPECT_TRUE(n[0].is_number_integer());
  EXPECT_EQ(n[1].get<int>(), -7);
  EXPECT_EQ(n[2].get<int>(), 3);
  EXPECT_EQ(n[3].get<double>(), 1.5);
  EXPECT_EQ(n[4].get<double>(), 0.5);
  EXPECT_EQ(n[5].get<double>(), 2.0);
  EXPECT_TRUE(n[6].is_number_float());
  EXPECT_EQ(n[7].get<double>(), -0.025);
  EXPECT_EQ(n[8].get<std::int64_t>(), INT64_MAX);
  EXPECT_EQ(n[9].get<std::uint64_t>(), UINT64_MAX);
  EXPECT_EQ(n[10].get<std::int64_t>(), INT64_MIN);
  EXPECT_THAT(bad("(18446744073709551616,)").error, HasSubstr("integer out of range"));
  EXPECT_THAT(bad("(1e999,)").error, HasSubstr("out of range"));
  EXPECT_THAT(bad("(-1e999,)").error, HasSubstr("out of range"));
  // too small for a double is 0.0, as Python reads it (issue #17, item 9: was an error)
  const json tiny = ok("[1e-400, -1e-400, 5e-324, 1e-310]");
  EXPECT_EQ(tiny[0].get<double>(), 0.0);
  EXPECT_TRUE(tiny[0].is_number_float());
  EXPECT_TRUE(std::signbit(tiny[1].get<double>()));
  EXPECT_EQ(tiny[2].get<double>(), 5e-324);
  EXPECT_EQ(tiny[3].get<double>(), 1e-310);
  EXPECT_THAT(bad("(01,)").error, HasSubstr("leading zeros"));
  EXPECT_THAT(bad("(1e,)").error, HasSubstr("exponent"));
  EXPECT_THAT(bad("(0x10,)").error, HasSubstr("malformed number"));
  EXPECT_THAT(bad("(-,)").error, HasSubstr("malformed number"));
  // around the length where plain integers leave the fast path (18 digits)
  json m = ok(
      "[12345678901234567, 123456789012345678, -123456789012345678, 1234567890123456789, -0, 7]");
  EXPECT_EQ(m[0].get<std::int64_t>(), 12345678901234567);
  EXPECT_EQ(m[1].get<std::int64_t>(), 123456789012345678);
  EXPECT_EQ(m[2].get<std::int64_t>(), -123456789012345678);
  EXPECT_EQ(m[3].get<std::int64_t>(), 1234567890123456789);
  EXPECT_TRUE(m[4].is_number_integer());
  EXPECT_EQ(m[4].get<std::int64_t>(), 0);
  EXPECT_EQ(m[5].get<std::int64_t>(), 7);
  EXPECT_EQ(ok("{'a':1,'b':-2}"), json::parse(R"({"a":1,"b":-2})"));
  EXPECT_EQ(ok("  42  "), json(42));
  EXPECT_THAT(bad("(12abc,)").error, HasSubstr("malformed number: unexpected 'a'"));
  EXPECT_THAT(bad("[1 2]").error, HasSubstr("expected ',' or ']'"));
}

TEST(SocketParamsParser, StringsWithBothQuotesAndEscapes) {
  EXPECT_EQ(ok("('a', \"b\")"), json::parse(R"(["a","b"])"));
  EXPECT_EQ(ok(R"(['it\'s', "say \"hi\""])"), json::parse(R"(["it's","say \"hi\""])"));
  EXPECT_EQ(ok(R"(['\n\t\r\\\/\x41\u00e9\U0001F600'])"),
            json::array({"\n\t\r\\/A\xc3\xa9\xf0\x9f\x98\x80"}));
  EXPECT_EQ(ok(R"(["\ud83d\ude00"])"), json::array({"\xf0\x9f\x98\x80"}));
  EXPECT_EQ(ok("['caf\xc3\xa9']"), json::array({"caf\xc3\xa9"}));
}

TEST(SocketParamsParser, MalformedStrings) {
  EXPECT_THAT(bad("('abc,)").error, HasSubstr("unterminated string"));
  EXPECT_THAT(bad(R"(('\q',))").error, HasSubstr("unknown escape sequence '\\q'"));
  EXPECT_THAT(bad(R"(('\u12',))").error, HasSubstr("escape"));
  EXPECT_THAT(bad(R"(('\uzzzz',))").error, HasSubstr("hexadecimal"));
  EXPECT_THAT(bad(R"(('\ud83d',))").error, HasSubstr("surrogate"));
  EXPECT_THAT(bad(R"(('\ude00',))").error, HasSubstr("surrogate"));
  EXPECT_THAT(bad(R"(('\U00110000',))").error, HasSubstr("code point"));
  EXPECT_THAT(bad("('\xc3\x28',)").error, HasSubstr("invalid UTF-8"));
  EXPECT_THAT(bad("('\xed\xa0\x80',)").error, HasSubstr("invalid UTF-8"));  // encoded surrogate
  EXPECT_THAT(bad("('\xc0\xaf',)").error, HasSubstr("invalid UTF-8"));      // overlong
  EXPECT_THAT(bad(std::string("('a\x01',)")).error, HasSubstr("control character"));
}

TEST(SocketParamsParser, DictsAreNamedArgumentsWithStringKeys) {
  EXPECT_EQ(ok("{'a': 1, \"b\": [2, 3],}"), json::parse(R"({"a":1,"b":[2,3]})"));
  EXPECT_EQ(ok("{}"), json::object());
  EXPECT_THAT(bad("{1: 2}").error, HasSubstr("expected a string key"));
  EXPECT_THAT(bad("{'a' 2}").error, HasSubstr("expected ':'"));
  EXPECT_THAT(bad("{'a': 2 'b': 3}").error, HasSubstr("expected ',' or '}'"));
  EXPECT_THAT(bad("{1, 2}").error, HasSubstr("string key"));  // no sets
  // a repeated key: the last value wins, whatever the first one was (as Python's dict)
  EXPECT_EQ(ok("{'a': [1, [2]], 'a': 3}"), json::parse(R"({"a":3})"));
  EXPECT_EQ(ok("{'a': [1, [2]], 'a': [4]}"), json::parse(R"({"a":[4]})"));
  EXPECT_EQ(ok("{'a': {'b': 1}, 'a': {'c': 2}}"), json::parse(R"({"a":{"c":2}})"));
}

TEST(SocketParamsParser, NothingIsEvaluated) {
  EXPECT_THAT(bad("(__import__('os').system('true'),)").error,
              HasSubstr("unknown name '__import__'"));
  EXPECT_THAT(bad("(1+1,)").error, HasSubstr("expected ',' or ')'"));
  EXPECT_THAT(bad("(x,)").error, HasSubstr("unknown name 'x'"));
  EXPECT_THAT(bad("(lambda: 0,)").error, HasSubstr("unknown name 'lambda'"));
}

TEST(SocketParamsParser, BareValuesAreAnErrorThatShowsTheListMeant) {
  EXPECT_EQ(bad("0.5 0.2").example, "[0.5, 0.2]");
  EXPECT_EQ(bad(" 0.5,  0.2 ").example, "[0.5, 0.2]");
  EXPECT_EQ(bad("1 'a' True None").example, "[1, \"a\", true, null]");
  EXPECT_EQ(bad("(1, 2) 3").example, "[[1, 2], 3]");
}

TEST(SocketParamsParser, OtherErrorsShowNoList) {
  EXPECT_EQ(bad("[1, 2] extra").example, "");
  EXPECT_EQ(bad("0.5 x").example, "");
  EXPECT_EQ(bad("(1,2").example, "");
  // a reused result forgets the previous example
  ParamsParse reused;
  json value;
  EXPECT_FALSE(parse_params_into("1 2", 1, value, reused));
  EXPECT_EQ(reused.example, "[1, 2]");
  EXPECT_FALSE(parse_params_into("(1,", 1, value, reused));
  EXPECT_EQ(reused.example, "");
  EXPECT_EQ(ok("0.5"), json(0.5));  // one bare value is a value (the core says it is not a list)
}

TEST(SocketParamsParser, ErrorsSayWhereWithTheLineColumn) {
  ParamsParse p = parse_params("(1, 2", 20);
  EXPECT_EQ(p.error, "expected ',' or ')' in tuple but found the end of the parameters");
  EXPECT_EQ(p.column, 25u);
  p = parse_params("[1, @]", 1);
  EXPECT_EQ(p.error, "expected a value but found '@'");
  EXPECT_EQ(p.column, 5u);
  p = parse_params("[1] [2]", 1);
  EXPECT_EQ(p.error, "unexpected '[' after the end of the parameters");
  EXPECT_EQ(p.column, 5u);
  p = parse_params("(\xff)", 1);
  EXPECT_EQ(p.error, "expected a value but found byte 0xff");
  EXPECT_EQ(p.column, 2u);
  p = parse_params("(1,", 1);
  EXPECT_EQ(p.error, "expected a value but found the end of the parameters");
}

TEST(SocketParamsParser, NestingIsLimited) {
  std::string ok_depth = std::string(k_max_depth, '[') + std::string(k_max_depth, ']');
  EXPECT_TRUE(parse_params(ok_depth).ok);
  std::string too_deep = std::string(k_max_depth + 1, '[') + std::string(k_max_depth + 1, ']');
  EXPECT_THAT(bad(too_deep).error, HasSubstr("nesting deeper than 64"));
  // a hostile line cannot exhaust the stack
  std::string hostile(100000, '(');
  EXPECT_THAT(bad(hostile).error, HasSubstr("nesting deeper"));
  std::string dicts;
  for (int i = 0; i < 100; ++i) dicts += "{'a': ";
  EXPECT_THAT(bad(dicts).error, HasSubstr("nesting deeper"));
}

TEST(SocketParamsParser, ParsingIntoAReusedValueRefillsItsArray) {
  ParamsParse error;
  json value;
  ASSERT_TRUE(parse_params_into("[1, [2, 3], {'k': 'v'}, 4]", 1, value, error));
  EXPECT_EQ(value, json::parse(R"([1, [2, 3], {"k": "v"}, 4])"));
  const json::array_t* array = &value.get_ref<const json::array_t&>();

  // a shorter list or a tuple refills the same array: nothing of the old content stays
  ASSERT_TRUE(parse_params_into("(5,)", 1, value, error));
  EXPECT_EQ(value, json::array({5}));
  EXPECT_EQ(&value.get_ref<const json::array_t&>(), array);
  ASSERT_TRUE(parse_params_into("[]", 1, value, error));
  EXPECT_EQ(value, json::array());

  // other shapes replace it
  ASSERT_TRUE(parse_params_into("{'a': 1}", 1, value, error));
  EXPECT_EQ(value, json({{"a", 1}}));
  ASSERT_TRUE(parse_params_into("  ", 1, value, error));
  EXPECT_TRUE(value.is_null());
  ASSERT_TRUE(parse_params_into("[True, None]", 1, value, error));
  EXPECT_EQ(value, json::parse("[true, null]"));

  // errors are reported as parse_params() reports them
  EXPECT_FALSE(parse_params_into("[1, 2", 10, value, error));
  ParamsParse same = parse_params("[1, 2", 10);
  EXPECT_EQ(error.error, same.error);
  EXPECT_EQ(error.column, same.column);
  ASSERT_TRUE(parse_params_into("[7]", 1, value, error));
  EXPECT_EQ(value, json::array({7}));
}

}  // namespace
}  // namespace simgate::socket
