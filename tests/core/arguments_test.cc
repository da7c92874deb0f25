// Conversion of JSON arguments to C++ parameter types (core/include/simgate/core/arguments.h).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "simgate/core/arguments.h"
#include "simgate/core/eigen.h"
#include "test_manager.h"

namespace simgate {
namespace {

using ::testing::HasSubstr;

template <class T>
std::string mismatch(const json& j) {
  try {
    (void)ArgTraits<T>::from_json(j);
  } catch (const TypeMismatch& m) {
    return "expected " + m.expected + " at '" + m.where + "', found " + m.found;
  }
  return "no mismatch";
}

TEST(ArgumentsTest, IntegersAcceptIntegralNumbersOnly) {
  EXPECT_EQ(ArgTraits<int>::from_json(json(5)), 5);
  EXPECT_EQ(ArgTraits<int>::from_json(json(5.0)), 5);
  EXPECT_THAT(mismatch<int>(json(5.5)), HasSubstr("expected integer"));
  EXPECT_THAT(mismatch<int>(json("5")), HasSubstr("found string \"5\""));
  EXPECT_THAT(mismatch<int>(json(true)), HasSubstr("found boolean true"));
}

TEST(ArgumentsTest, IntegersAreRangeChecked) {
  EXPECT_THAT(mismatch<std::int8_t>(json(300)), HasSubstr("in range"));
  EXPECT_THAT(mismatch<unsigned>(json(-1)), HasSubstr("non-negative"));
  EXPECT_EQ(ArgTraits<std::uint64_t>::from_json(json(18446744073709551615ull)),
            18446744073709551615ull);
  // both JSON integer kinds at both ends, into both C++ kinds
  EXPECT_EQ(ArgTraits<std::int64_t>::from_json(json(std::uint64_t{9223372036854775807u})),
            INT64_MAX);
  EXPECT_THAT(mismatch<std::int64_t>(json(std::uint64_t{9223372036854775808u})),
              HasSubstr("in range"));
  EXPECT_EQ(ArgTraits<std::int64_t>::from_json(json(std::int64_t{-9223372036854775807 - 1})),
            INT64_MIN);
  EXPECT_EQ(ArgTraits<std::uint8_t>::from_json(json(std::uint64_t{255})), 255);
  EXPECT_THAT(mismatch<std::uint8_t>(json(std::uint64_t{256})), HasSubstr("in range"));
  EXPECT_DOUBLE_EQ(ArgTraits<double>::from_json(json(std::uint64_t{18446744073709551615u})),
                   18446744073709551615.0);
  EXPECT_DOUBLE_EQ(ArgTraits<float>::from_json(json(-3)), -3.0f);
}

TEST(ArgumentsTest, IntegralFloatsAreRangeCheckedUpToTheLastBit) {
  // double(UINT64_MAX) and double(INT64_MAX) round up to 2^64 and 2^63, which do not fit:
  // converting them was undefined behaviour (found by the fuzz target jsonrpc_message,
  // tests/fuzz/corpus/arguments/float_at_2_pow_64)
  EXPECT_THAT(mismatch<std::uint64_t>(json(18446744073709551616.0)),
              HasSubstr("expected non-negative integer"));
  EXPECT_THAT(mismatch<std::int64_t>(json(9223372036854775808.0)), HasSubstr("expected integer"));
  EXPECT_THAT(mismatch<std::uint32_t>(json(4294967296.0)),
              HasSubstr("expected non-negative integer"));
  EXPECT_THAT(mismatch<std::int8_t>(json(128.0)), HasSubstr("expected integer"));
  EXPECT_THAT(mismatch<std::int8_t>(json(-129.0)), HasSubstr("expected integer"));
  // the ends that fit still bind
  EXPECT_EQ(ArgTraits<std::uint64_t>::from_json(json(18446744073709549568.0)),
            18446744073709549568ull);  // 2^64 - 2^11
  EXPECT_EQ(ArgTraits<std::int64_t>::from_json(json(-9223372036854775808.0)), INT64_MIN);
  EXPECT_EQ(ArgTraits<std::int64_t>::from_json(json(9223372036854774784.0)),
            9223372036854774784);  // 2^63 - 2^10
  EXPECT_EQ(ArgTraits<std::uint32_t>::from_json(json(4294967295.0)), 4294967295u);
  EXPECT_EQ(ArgTraits<std::int8_t>::from_json(json(127.0)), 127);
  EXPECT_EQ(ArgTraits<std::int8_t>::from_json(json(-128.0)), -128);
  EXPECT_EQ(ArgTraits<std::uint8_t>::from_json(json(0.0)), 0);
}

TEST(ArgumentsTest, FloatingPointAcceptsAnyNumber) {
  EXPECT_DOUBLE_EQ(ArgTraits<double>::from_json(json(2)), 2.0);
  EXPECT_DOUBLE_EQ(ArgTraits<double>::from_json(json(1.5)), 1.5);
  EXPECT_THAT(mismatch<double>(json(nullptr)), HasSubstr("expected number"));
}

TEST(ArgumentsTest, BoolsAndStringsAreStrict) {
  EXPECT_TRUE(ArgTraits<bool>::from_json(json(true)));
  EXPECT_THAT(mismatch<bool>(json(1)), HasSubstr("expected boolean"));
  EXPECT_EQ(ArgTraits<std::string>::from_json(json("héllo")), "héllo");
  EXPECT_THAT(mismatch<std::string>(json(3)), HasSubstr("expected string"));
}

TEST(ArgumentsTest, ContainersLocateTheBadElement) {
  EXPECT_EQ(ArgTraits<std::vector<int>>::from_json(json{1, 2, 3}), (std::vector<int>{1, 2, 3}));
  EXPECT_THAT(mismatch<std::vector<int>>(json{1, "x"}), HasSubstr("at '[1]'"));
  EXPECT_THAT(mismatch<std::vector<std::vector<double>>>(json{{1.0}, {2.0, "y"}}),
              HasSubstr("at '[1][1]'"));
  EXPECT_THAT((mismatch<std::array<double, 3>>(json{1, 2})), HasSubstr("array of 3 numbers"));
  EXPECT_THAT((mismatch<std::map<std::string, int>>(json{{"a", 1}, {"b", "no"}})),
              HasSubstr("at '.b'"));
}

TEST(ArgumentsTest, OptionalAcceptsNull) {
  EXPECT_FALSE(ArgTraits<std::optional<int>>::from_json(json(nullptr)).has_value());
  EXPECT_EQ(ArgTraits<std::optional<int>>::from_json(json(4)), 4);
}

TEST(ArgumentsTest, EigenVectorsConvertBothWays) {
  Eigen::Vector3d v = ArgTraits<Eigen::Vector3d>::from_json(json{1.0, 2.0, 3.0});
  EXPECT_EQ(v, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(ArgTraits<Eigen::Vector3d>::to_json(v), (json{1.0, 2.0, 3.0}));
  EXPECT_THAT(mismatch<Eigen::Vector3d>(json{1.0, 2.0}), HasSubstr("array of 3 numbers"));
  EXPECT_EQ(ArgTraits<Eigen::VectorXd>::from_json(json{1, 2, 3, 4}).size(), 4);
}

TEST(ArgumentsTest, SchemasDescribeTypes) {
  EXPECT_EQ(ArgTraits<double>::schema(), (json{{"type", "number"}}));
  EXPECT_EQ(ArgTraits<std::vector<int>>::schema()["items"]["type"], "integer");
  EXPECT_EQ(ArgTraits<Eigen::Vector3d>::schema()["maxItems"], 3);
}

int sum9(int a, int b, int c, int d, int e, int f, int g, int h, int i) {
  return a + b + c + d + e + f + g + h + i;
}

TEST(BoundArgumentsTest, MoreParametersThanTheInlineBufferStillBind) {
  testing::TestManager rm;
  rm.register_service("c", sum9, "sum9", {"a", "b", "c", "d", "e", "f", "g", "h", {"i", 100}});
  auto positional = rm.run("c", "sum9", json::array({1, 2, 3, 4, 5, 6, 7, 8, 9}));
  ASSERT_TRUE(positional);
  EXPECT_EQ(positional->value, json(45));
  auto with_default = rm.run("c", "sum9", json::array({1, 2, 3, 4, 5, 6, 7, 8}));
  ASSERT_TRUE(with_default);
  EXPECT_EQ(with_default->value, json(136));
  auto named = rm.run("c", "sum9",
                      json{{"i", 1},
                           {"h", 1},
                           {"g", 1},
                           {"f", 1},
                           {"e", 1},
                           {"d", 1},
                           {"c", 1},
                           {"b", 1},
                           {"a", 1}});
  ASSERT_TRUE(named);
  EXPECT_EQ(named->value, json(9));
  auto too_few = rm.run("c", "sum9", json::array({1, 2}));
  ASSERT_TRUE(too_few);
  EXPECT_EQ(too_few->failure, Failure::bad_arguments);
  EXPECT_THAT(too_few->message, ::testing::HasSubstr("expected 8 to 9"));
  auto missing = rm.run("c", "sum9", json{{"a", 1}, {"b", 2}, {"i", 3}});
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->failure, Failure::bad_arguments);
  EXPECT_THAT(missing->message, ::testing::HasSubstr("missing 'c', 'd', 'e', 'f', 'g', 'h'"));
}

}  // namespace
}  // namespace simgate
