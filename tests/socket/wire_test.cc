// The socket transport's line grammar and Python-compatible JSON formatting.
#include "simgate/morse/wire.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

namespace simgate::socket {
namespace {

using ::testing::HasSubstr;
using Kind = RequestLine::Kind;

std::string dumps(const json& value) {
  std::string out;
  append_json(out, value);
  return out;
}

TEST(SocketWire, RequestTokens) {
  RequestLine r = parse_request_line("req1 test_component add (1,2)");
  EXPECT_EQ(r.kind, Kind::call);
  EXPECT_EQ(r.id, "req1");
  EXPECT_EQ(r.component, "test_component");
  EXPECT_EQ(r.service, "add");
  EXPECT_EQ(r.params, "(1,2)");
  EXPECT_EQ(r.params_column, 25u);
}

TEST(SocketWire, AnyBlanksBetweenTokensAndAroundTheLine) {
  RequestLine r = parse_request_line("  \tid \t comp\t\tsvc   [1,  2]  \r");
  EXPECT_EQ(r.kind, Kind::call);
  EXPECT_EQ(r.id, "id");
  EXPECT_EQ(r.component, "comp");
  EXPECT_EQ(r.service, "svc");
  EXPECT_EQ(r.params, "[1,  2]");
  r = parse_request_line("id comp svc\r");
  EXPECT_EQ(r.kind, Kind::call);
  EXPECT_EQ(r.service, "svc");
  EXPECT_EQ(r.params, "");
}

TEST(SocketWire, CancelBlankAndMalformed) {
  EXPECT_EQ(parse_request_line("x1 cancel").kind, Kind::cancel);
  EXPECT_EQ(parse_request_line(" x1\tcancel \r").kind, Kind::cancel);
  EXPECT_EQ(parse_request_line("x1 cancel now").kind, Kind::call);  // component "cancel"
  EXPECT_EQ(parse_request_line("").kind, Kind::blank);
  EXPECT_EQ(parse_request_line(" \t\r").kind, Kind::blank);
  RequestLine alone = parse_request_line("x1");
  EXPECT_EQ(alone.kind, Kind::malformed);
  EXPECT_EQ(alone.id, "x1");
  EXPECT_THAT(alone.error, HasSubstr("Malformed request!"));
  RequestLine two = parse_request_line("x1 comp");
  EXPECT_EQ(two.kind, Kind::malformed);
  EXPECT_THAT(two.error, HasSubstr("missing the service name"));
  RequestLine utf = parse_request_line("x1 comp sv\xc3");
  EXPECT_EQ(utf.kind, Kind::malformed);
  EXPECT_THAT(utf.error, HasSubstr("service name is not valid UTF-8 (column 11)"));
}

// Ids are echoed verbatim: one with an escape sequence made a telnet user's terminal act on
// it (issue #17, item 9). Refused, answered under "-".
TEST(SocketWire, AnIdWithAControlCharacterIsMalformedAndNotEchoed) {
  RequestLine esc = parse_request_line(" a\x1b[2J robot.pose get_local_data");
  EXPECT_EQ(esc.kind, Kind::malformed);
  EXPECT_EQ(esc.id, "-");
  EXPECT_EQ(esc.error,
            "Malformed request! the id contains a control character (byte 27 at column 3); ids are "
            "echoed in replies, use printable ones");
  EXPECT_EQ(parse_request_line(std::string("x\x7f comp sv")).id, "-");
  EXPECT_EQ(parse_request_line("\xc3\xa9t\xc3\xa9 comp sv").kind,
            Kind::call);  // UTF-8 ids are fine
  EXPECT_TRUE(echoable_id("req-42"));
  EXPECT_FALSE(echoable_id(std::string("a\0b", 3)));
}

// parse_request_line reads tokens eight bytes at a time: checked against a byte-by-byte
// reading of the grammar on random lines of blanks, controls, 0x7f, non-ASCII bytes and
// letters, with tokens of every length across the word boundaries.
struct ByteByByte {
  Kind kind = Kind::blank;
  std::string id, component, service, params;
  std::size_t params_column = 0;
  bool error = false;
};

ByteByByte read_byte_by_byte(std::string_view line) {
  const auto blank = [](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
  };
  std::size_t pos = 0;
  const auto token = [&] {
    while (pos < line.size() && blank(line[pos])) ++pos;
    const std::size_t begin = pos;
    while (pos < line.size() && !blank(line[pos])) ++pos;
    return std::pair{begin, std::string(line.substr(begin, pos - begin))};
  };
  ByteByByte r;
  const auto [id_begin, id] = token();
  if (id.empty()) return r;
  r.kind = Kind::malformed;
  r.error = true;
  for (char c : id)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      r.id = "-";
      return r;
    }
  r.id = id;
  const auto [c_begin, component] = token();
  if (component.empty()) return r;
  r.component = component;
  const auto [s_begin, service] = token();
  if (service.empty()) {
    if (component == "cancel") {
      r.kind = Kind::cancel;
      r.error = false;
    }
    r.component.clear();
    return r;
  }
  r.service = service;
  while (pos < line.size() && blank(line[pos])) ++pos;
  std::size_t end = line.size();
  while (end > pos && blank(line[end - 1])) --end;
  r.params = line.substr(pos, end - pos);
  r.params_column = pos + 1;
  std::size_t bad = 0;
  if (!valid_utf8(component, bad) || !valid_utf8(service, bad)) {
    r.component = r.service = r.params = "";
    r.params_column = 0;
    return r;
  }
  r.kind = Kind::call;
  r.error = false;
  return r;
}

TEST(SocketWire, TokensReadByWordsAgreeWithAByteByByteReading) {
  const std::string alphabet[] = {" ",    "\t",   "\r",   "\f",   "\v",       "a",   "b",
                                  "Z",    "0",    "7",    "_",    ".",        "[",   "\x01",
                                  "\x1b", "\x1f", "\x7f", "\x80", "\xc3\xa9", "\xff"};
  std::mt19937 random(2024);
  for (int i = 0; i < 200000; ++i) {
    std::string line;
    const std::size_t parts = random() % 40;
    for (std::size_t k = 0; k < parts; ++k) {
      // mostly letters, so that tokens grow past eight bytes
      const std::size_t pick =
          random() % 4 == 0 ? random() % std::size(alphabet) : 5 + random() % 3;
      line += alphabet[pick];
    }
    const RequestLine r = parse_request_line(line);
    const ByteByByte expected = read_byte_by_byte(line);
    ASSERT_EQ(r.kind, expected.kind) << testing::PrintToString(line);
    ASSERT_EQ(!r.error.empty(), expected.error) << testing::PrintToString(line);
    ASSERT_EQ(r.id, expected.id) << testing::PrintToString(line);
    if (r.kind != Kind::call) continue;
    ASSERT_EQ(r.component, expected.component) << testing::PrintToString(line);
    ASSERT_EQ(r.service, expected.service) << testing::PrintToString(line);
    ASSERT_EQ(r.params, expected.params) << testing::PrintToString(line);
    ASSERT_EQ(r.params_column, expected.params_column) << testing::PrintToString(line);
  }
}

TEST(SocketWire, JsonLikePythonDumps) {
  EXPECT_EQ(dumps(json::parse(R"([1, "a", {"k": [true, false, null]}, 2.5, -3])")),
            R"([1, "a", {"k": [true, false, null]}, 2.5, -3])");
  EXPECT_EQ(dumps(json::parse(R"({"a": 1, "b": {}})")), R"({"a": 1, "b": {}})");
  EXPECT_EQ(dumps(1.0), "1.0");
  EXPECT_EQ(dumps(0.1), "0.1");
  EXPECT_EQ(dumps(1e-5), "1e-05");
  EXPECT_EQ(dumps(1e16), "1e+16");
  EXPECT_EQ(dumps(std::uint64_t(18446744073709551615ull)), "18446744073709551615");
  EXPECT_EQ(dumps(NAN), "NaN");
  EXPECT_EQ(dumps(-INFINITY), "-Infinity");
}

// Every float is written as Python's repr writes it, digit for digit: checked against
// /usr/bin/python3 itself on random bit patterns, on values around the switches between
// fixed and scientific notation (1e-4, 1e16), and on the edges of the double range.
TEST(SocketWire, FloatsAreWrittenExactlyAsPythonReprWritesThem) {
  std::vector<double> values = {0.0,
                                -0.0,
                                1.0,
                                -1.0,
                                0.1,
                                0.2 + 0.1,
                                1.0 / 3,
                                2.5,
                                100.0,
                                123456.789,
                                1e-4,
                                9.999999999999999e-5,
                                1e-5,
                                0.00012,
                                1.5e-4,
                                1e15,
                                1e16,
                                9999999999999998.0,
                                1.2345678901234567e16,
                                1e22,
                                1e23,
                                5e-324,
                                2.2250738585072014e-308,
                                1.7976931348623157e308,
                                4.35,
                                0.3};
  std::mt19937_64 random(18);
  for (int i = 0; i < 4000; ++i) {  // any finite bit pattern
    std::uint64_t bits = random();
    double d;
    std::memcpy(&d, &bits, sizeof d);
    if (std::isfinite(d)) values.push_back(d);
  }
  std::uniform_real_distribution<double> unit(-1, 1);
  for (int exponent = -8; exponent <= 20; ++exponent)  // sensor-like values at every scale
    for (int i = 0; i < 100; ++i) values.push_back(unit(random) * std::pow(10.0, exponent));
  for (int i = 0; i < 200; ++i)
    values.push_back(std::round(unit(random) * 1e6) / 64);  // few digits

  const auto dir = std::filesystem::temp_directory_path();
  const auto in_path = dir / ("simgate_repr_in_" + std::to_string(::getpid()));
  {
    std::ofstream in(in_path);
    char hex[64];
    for (double d : values) {
      std::snprintf(hex, sizeof hex, "%a\n", d);
      in << hex;
    }
  }
  const std::string command =
      "/usr/bin/python3 -c 'import sys\nfor l in sys.stdin: print(repr(float.fromhex(l)))' < " +
      in_path.string();
  FILE* python = ::popen(command.c_str(), "r");
  ASSERT_NE(python, nullptr);
  std::vector<std::string> expected;
  char line[128];
  while (std::fgets(line, sizeof line, python))
    expected.emplace_back(line, std::strcspn(line, "\n"));
  const int status = ::pclose(python);
  std::filesystem::remove(in_path);
  ASSERT_EQ(status, 0) << command;
  ASSERT_EQ(expected.size(), values.size());
  int mismatches = 0;
  for (std::size_t i = 0; i < values.size() && mismatches < 10; ++i) {
    const std::string ours = dumps(values[i]);
    if (ours != expected[i]) ++mismatches;
    EXPECT_EQ(ours, expected[i]) << "value " << i;
  }
}

TEST(SocketWire, StringsAreAsciiEscapedLikePython) {
  EXPECT_EQ(dumps("caf\xc3\xa9"), R"("caf\u00e9")");
  EXPECT_EQ(dumps("\xf0\x9f\x98\x80"), R"("\ud83d\ude00")");
  EXPECT_EQ(dumps("a\"b\\c\n\t\r\b\f"), R"("a\"b\\c\n\t\r\b\f")");
  EXPECT_EQ(dumps(std::string("\x01\x7f/", 3)), R"("\u0001\u007f/")");
  // invalid UTF-8 never breaks a reply
  EXPECT_EQ(dumps("a\xff"
                  "b\xc3"),
            R"("a\ufffdb\ufffd")");
}

TEST(SocketWire, ReplyLines) {
  std::string out;
  append_reply(out, "req1", "SUCCESS", nullptr);
  json three = 3;
  append_reply(out, "req2", "OK", &three);
  json message = "no";
  append_reply(out, "r3", "FAILED", &message);
  EXPECT_EQ(out, "req1 SUCCESS\nreq2 OK 3\nr3 FAILED \"no\"\n");

  // integers are written in one piece: the extremes of both JSON integer kinds
  out.clear();
  json values[] = {json(std::int64_t{-9223372036854775807 - 1}),
                   json(std::uint64_t{18446744073709551615u}),
                   json(0),
                   json(-7),
                   json(2.5),
                   json::array({1, 2})};
  for (const auto& v : values) append_reply(out, "i", "SUCCESS", &v);
  EXPECT_EQ(out,
            "i SUCCESS -9223372036854775808\ni SUCCESS 18446744073709551615\ni SUCCESS 0\n"
            "i SUCCESS -7\ni SUCCESS 2.5\ni SUCCESS [1, 2]\n");
}

}  // namespace
}  // namespace simgate::socket
