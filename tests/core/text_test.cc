// simgate/core/text.h: same_text and assign_text, the hot path's compare and copy of short
// names and ids.
#include <gtest/gtest.h>

#include <string>

#include "simgate/core/text.h"

namespace simgate {
namespace {

TEST(SameText, AgreesWithEqualityForEveryLengthAndEveryDifferingByte) {
  const std::string source = "abcdefghijklmnopqrstuvwxyz0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ";
  for (std::size_t n = 0; n <= 40; ++n) {
    const std::string a = source.substr(5, n);
    std::string b = a;
    EXPECT_TRUE(same_text(a, b)) << n;
    for (std::size_t i = 0; i < n; ++i) {  // one byte differs, wherever it is
      b[i] ^= 0x20;
      EXPECT_FALSE(same_text(a, b)) << n << " at " << i;
      b[i] ^= 0x20;
    }
    EXPECT_FALSE(same_text(a, a + "x")) << n;
    if (n > 0) {
      EXPECT_FALSE(same_text(a, std::string_view(a).substr(1))) << n;
    }
  }
  EXPECT_TRUE(same_text(std::string_view(), ""));
}

TEST(AssignText, CopiesEveryLengthIntoShorterLongerAndLargerStrings) {
  // every length up to past the inline copies, into strings that held shorter and longer
  // texts, within their capacity and beyond it
  const std::string source = "abcdefghijklmnopqrstuvwxyz0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ";
  for (std::size_t n = 0; n <= 40; ++n) {
    const std::string_view text(source.data() + 3, n);
    for (const std::size_t before : {0u, 1u, 5u, 9u, 15u, 16u, 20u, 64u}) {
      std::string dest(before, '#');
      assign_text(dest, text);
      ASSERT_EQ(dest, text) << n << " after " << before;
      ASSERT_EQ(dest.size(), n);
      ASSERT_EQ(dest.c_str()[n], '\0');
    }
  }
  std::string dest = "kept";
  assign_text(dest, std::string_view());
  EXPECT_TRUE(dest.empty());
}

TEST(AssignText, KeepsTheBufferWhenTheTextFits) {
  std::string dest(100, 'x');
  const char* buffer = dest.data();
  assign_text(dest, "a longer id than the small-string buffer holds, 50 b");
  EXPECT_EQ(dest.data(), buffer);
  assign_text(dest, "7");
  EXPECT_EQ(dest, "7");
  EXPECT_EQ(dest.data(), buffer);
}

}  // namespace
}  // namespace simgate
