// The JSON-RPC fast path (protocol.h: parse_request_fast, append_result_line) against the
// full path it short-cuts (json::parse + parse_request, result_line): on a corpus of valid
// and invalid messages, and on every one-byte mutation of the valid ones, the fast path
// either declines or reads exactly what the full path reads, down to the JSON number types;
// and the common shapes do take it.
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "simgate/jsonrpc/protocol.h"
#include "simgate/core/config.h"

namespace simgate::jsonrpc {
namespace {

constexpr std::size_t k_max_depth = 8;

// The reply line as the full path would write it: dump() of each part, around the envelope.
std::string result_line(const json& id, const json& result) {
  return R"({"jsonrpc":"2.0","id":)" + dump(id) + R"(,"result":)" + dump(result) + "}";
}

// Same value and, recursively, the same JSON types (json's == equates 1u, 1 and 1.0).
bool identical(const json& a, const json& b) {
  if (a.type() != b.type()) return false;
  if (a.is_array()) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
      if (!identical(a[i], b[i])) return false;
    return true;
  }
  if (a.is_object()) {
    if (a.size() != b.size()) return false;
    for (auto it = a.begin(), jt = b.begin(); it != a.end(); ++it, ++jt)
      if (it.key() != jt.key() || !identical(it.value(), jt.value())) return false;
    return true;
  }
  if (a.is_number_float())
    return dump(a) == dump(b) && std::signbit(a.get<double>()) == std::signbit(b.get<double>());
  return a == b;
}

// What the full path reads: the request, or nullopt when it answers an error (parse error,
// invalid request, or anything json::parse throws). The depth pre-scan comes first, as in
// the transport.
std::optional<Request> full_path(const std::string& line) {
  if (json_nests_deeper_than(line, k_max_depth)) return std::nullopt;
  json message;
  try {
    message = json::parse(line);
  } catch (const json::exception&) {
    return std::nullopt;
  }
  Request request;
  if (parse_request(message, request)) return std::nullopt;
  return request;
}

// Checks one line, read into `fast` (which may hold an earlier request: the transport
// reuses one); returns whether the fast path took it.
bool check(const std::string& line, Request& fast) {
  const bool took = parse_request_fast(line, k_max_depth, fast);
  if (!took) return false;
  auto full = full_path(line);
  EXPECT_TRUE(full.has_value()) << "fast path accepted what the full path refuses: " << line;
  if (!full) return true;
  EXPECT_EQ(fast.has_id, full->has_id) << line;
  EXPECT_TRUE(identical(fast.id, full->id))
      << line << "\nfast: " << fast.id.dump() << "\nfull: " << full->id.dump();
  EXPECT_EQ(fast.method, full->method) << line;
  EXPECT_TRUE(identical(fast.params, full->params))
      << line << "\nfast: " << fast.params.dump() << "\nfull: " << full->params.dump();
  if (fast.has_id) {
    EXPECT_EQ(fast.id_text, dump(full->id)) << line;
  }
  return true;
}

bool check(const std::string& line) {
  Request fast;
  return check(line, fast);
}

// Valid requests of the shapes clients send, and near misses of each.
const std::vector<std::string> k_common = {
    R"({"jsonrpc":"2.0","id":1,"method":"test_component.add","params":[1,2]})",
    R"({"jsonrpc": "2.0", "method": "spec.subtract", "params": [42, 23], "id": 1})",
    R"({"jsonrpc": "2.0", "method": "spec.subtract", "params": {"subtrahend": 23, "minuend": 42}, "id": 3})",
    R"({"jsonrpc": "2.0", "method": "spec.update", "params": [1,2,3,4,5]})",
    R"({"jsonrpc": "2.0", "method": "spec.get_data", "id": "9"})",
    R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1.5,-2.25e3],"id":null})",
    R"( {"method":"robot.arm.echo","jsonrpc":"2.0","id":-7,"params":[true,false,null,"x y"]} )",
    R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[{"a":[1,{"b":"c\"d"}]}],"id":"s-1"})",
    R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":["caf\u00e9", "\n"],"id":0})",
    R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":{"k":1,"k":2},"id":12})",
    R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[-0, 0.0, -0.0, 1E2, 1e-2, 123456789012345678],"id":2})",
    R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[1234567890123456789, 18446744073709551616],"id":2})",
    R"({"jsonrpc":"2.0","method":"rpc.cancel","params":{"id":5},"id":6})",
    R"({"jsonrpc":"2.0","method":"rpc.discover","id":"d"})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":["]"],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":{},"id":1})",
    "{\"jsonrpc\":\"2.0\",\"method\":\"a.b\",\"params\":[\"\xc3\xa9\"],\"id\":1}",
    "{\t\"jsonrpc\"\r:\n\"2.0\" , \"method\":\"a.b\"}",
};

// Valid messages the fast path leaves to the full parser (repeated or unknown members,
// fractional ids).
const std::vector<std::string> k_declined = {
    R"({"jsonrpc":"2.0","method":"a.b","method":"c.d","id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","id":1,"id":2})",
    R"({"jsonrpc":"2.0","method":"a.b","id":1,"extra":true})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[1],"params":{"a":1}})",
    R"({"jsonrpc":"2.0","method":"a.b","id":1.5})",
};

// Messages the full path answers with an error.
const std::vector<std::string> k_invalid = {
    R"({"jsonrpc":"2.0","method":"a.b","params":[1,2],"id":1)",
    R"({"jsonrpc":"2.0","method":"a.b","params":[1,2],"id":1}})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[1,2],"id":1} x)",
    R"({"jsonrpc":"2.0","method":"a.b","params":[1,2,],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[01],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[1.],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[1e400],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[tru],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":"x","id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":null,"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","id":true})",
    R"({"jsonrpc":"2.0","method":"a.b","id":[1]})",
    R"({"jsonrpc":"2.1","method":"a.b","id":1})",
    R"({"jsonrpc":2.0,"method":"a.b","id":1})",
    R"({"method":"a.b","id":1})",
    R"({"jsonrpc":"2.0","id":1})",
    R"({"jsonrpc":"2.0","method":1,"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":[[[[[[[[[1]]]]]]]]],"id":1})",
    R"({"jsonrpc":"2.0","method":"a.b","params":["\x"],"id":1})",
    "{\"jsonrpc\":\"2.0\",\"method\":\"a.b\",\"params\":[\"\xff\"],\"id\":1}",
    "{\"jsonrpc\":\"2.0\",\"method\":\"a.b\",\"params\":[\"a\tb\"],\"id\":1}",
    R"([])",
    R"({})",
    R"(1)",
    R"("x")",
    R"({"jsonrpc":"2.0","method":"a.b","params":[1,2],"id":1}{"jsonrpc":"2.0","method":"a.b","id":2})",
};

TEST(JsonRpcFastPath, CommonShapesTakeTheFastPath) {
  for (
      const char* line :
      {R"({"jsonrpc":"2.0","id":1,"method":"test_component.add","params":[1,2]})",
       R"({"jsonrpc": "2.0", "method": "spec.subtract", "params": {"subtrahend": 23, "minuend": 42}, "id": 3})",
       R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1.5,-2.25e3],"id":"a"})",
       R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[{"a":[1,{"b":"c\"d"}]}],"id":null})",
       R"({"jsonrpc":"2.0","method":"spec.notify_hello","params":[7]})"})
    EXPECT_TRUE(check(line)) << "not taken: " << line;
}

TEST(JsonRpcFastPath, ReadsValidMessagesExactlyAsTheFullParser) {
  for (const auto& line : k_common) {
    check(line);
    EXPECT_TRUE(full_path(line).has_value()) << "corpus entry should be valid: " << line;
  }
}

TEST(JsonRpcFastPath, AReusedRequestCarriesNothingOver) {
  // the transport reads every message into one Request, whose params array it refills:
  // each message must read exactly as alone, whatever came before (longer arrays, objects,
  // no params, declined lines)
  Request fast;
  const std::vector<std::string> sequence = {
      R"({"jsonrpc":"2.0","id":1,"method":"a.b","params":[1,2,3,"x",[4]]})",
      R"({"jsonrpc":"2.0","id":2,"method":"a.b","params":[5]})",
      R"({"jsonrpc":"2.0","id":3,"method":"a.b","params":{"k":1}})",
      R"({"jsonrpc":"2.0","id":4,"method":"a.b"})",
      R"({"jsonrpc":"2.0","id":5,"method":"a.b","params":[]})",
      R"({"jsonrpc":"2.0","id":6,"method":"a.b","params":[1,2]})",
      R"([{"jsonrpc":"2.0","id":7,"method":"a.b","params":[9]}])",  // declined: a batch
      R"({"jsonrpc":"2.0","id":8,"method":"a.b","params":[6,7]})",
      R"({"jsonrpc":"2.0","method":"a.b"})",
      // elements and ids are overwritten in place: every change of type in every slot
      R"({"jsonrpc":"2.0","id":"s1","method":"a.b","params":[1,-2,0.5,"x",true,null]})",
      R"({"jsonrpc":"2.0","id":-3,"method":"a.b","params":["y",0.25,-7,false,null,8]})",
      R"({"jsonrpc":"2.0","id":null,"method":"a.b","params":[null,"z",true,1e3,-0,"w"]})",
      R"({"jsonrpc":"2.0","id":"","method":"a.b","params":[false,null,"",2,-1.5,true]})",
      R"({"jsonrpc":"2.0","id":9,"method":"a.b","params":[1,2,"three",[4]]})",    // declined
      R"({"jsonrpc":"2.0","id":10,"method":"a.b","params":[1,2,"thr\u0065e"]})",  // declined
      R"({"jsonrpc":"2.0","id":11,"method":"a.b","params":[3]})",
      R"({"jsonrpc":"2.0","id":-0,"method":"a.b","params":[3]})",  // id text "0", as dump()
      R"({"jsonrpc":"2.0","id":-12,"method":"a.b","params":[3]})",
      R"({"jsonrpc":"2.0","id":14,"method":"a.b","params":[-3,1.0]})",  // unsigned to signed
      R"({"jsonrpc":"2.0","id":15,"method":"a.b","params":[3,-1]})",    // and back; float to signed
      R"({"jsonrpc":"2.0","method":"a.b","params":[3,4]})"};
  for (const auto& line : sequence) check(line, fast);
  for (const auto& line : k_common) check(line, fast);
}

TEST(JsonRpcFastPath, EveryByteOfALongStringIsCheckedWordByWord) {
  // plain strings are scanned eight bytes at a time: a quote, backslash, control or
  // non-ASCII byte at any position of a word (and of the tail) must stop the scan there
  const std::string plain = "robot.arm.abcdefghijklmnopqrstu";  // 31 bytes: words and a tail
  const std::string envelope_head = R"({"jsonrpc":"2.0","id":1,"method":")";
  Request fast;
  ASSERT_TRUE(check(envelope_head + plain + R"(","params":[")" + plain + R"("]})", fast));
  for (const char special : {'"', '\\', '\x01', '\t', '\x1f', '\x7f', '\x80', '\xc3', '\xff'}) {
    for (std::size_t i = 0; i < plain.size(); ++i) {
      std::string bent = plain;
      bent[i] = special;
      const std::string in_method = envelope_head + bent + R"(","params":[1]})";
      const std::string in_param = envelope_head + plain + R"(","params":[")" + bent + R"("]})";
      for (const auto& line : {in_method, in_param}) {
        check(line, fast);  // declined, or read exactly as the full parser reads it
        if (special != '"' && special != '\\' && static_cast<unsigned char>(special) < 0x20) {
          EXPECT_FALSE(parse_request_fast(line, k_max_depth, fast))
              << "control byte " << static_cast<int>(special) << " at " << i;
        }
      }
    }
  }
}

TEST(JsonRpcFastPath, LeavesUnusualValidMessagesAndBatchesToTheFullParser) {
  for (const auto& line : k_declined) {
    Request fast;
    EXPECT_FALSE(parse_request_fast(line, k_max_depth, fast)) << line;
    EXPECT_TRUE(full_path(line).has_value() || line.front() == '[')
        << "corpus entry should be valid: " << line;
  }
  Request fast;
  EXPECT_FALSE(
      parse_request_fast(R"([{"jsonrpc":"2.0","method":"a.b","id":1}])", k_max_depth, fast));
}

TEST(JsonRpcFastPath, DeclinesEveryInvalidMessage) {
  for (const auto& line : k_invalid) {
    Request fast;
    EXPECT_FALSE(parse_request_fast(line, k_max_depth, fast)) << line;
    EXPECT_FALSE(full_path(line).has_value()) << "corpus entry should be invalid: " << line;
  }
}

TEST(JsonRpcFastPath, EveryOneByteMutationIsDeclinedOrReadIdentically) {
  // deletions, and replacements by bytes that matter to a JSON reader
  std::string bytes = "{}[],:\"\\ 0123456789-+.eEtrufalsn\t\x7f\x80\xc3";
  bytes += '\0';
  std::size_t cases = 0;
  for (const auto& base : k_common) {
    for (std::size_t i = 0; i < base.size(); ++i) {
      std::string deleted = base;
      deleted.erase(i, 1);
      check(deleted);
      ++cases;
      for (char c : bytes) {
        if (base[i] == c) continue;
        std::string replaced = base;
        replaced[i] = c;
        check(replaced);
        ++cases;
      }
    }
  }
  EXPECT_GT(cases, 10000u);
}

TEST(JsonRpcFastPath, ResultLineByHandIsTheSameBytes) {
  const std::vector<json> ids = {json(1),     json(-3),      json(0u),
                                 json("abc"), json(nullptr), json(std::uint64_t(1) << 63)};
  const std::vector<json> results = {json(3),
                                     json(-3),
                                     json(2.5),
                                     json(3.0),
                                     json(true),
                                     json(false),
                                     json(nullptr),
                                     json("x\"y\n\xff"),
                                     json::array({1, "a"}),
                                     json::object({{"b", 1}, {"a", 2}}),
                                     json(std::int64_t(-9223372036854775807 - 1))};
  for (const auto& id : ids)
    for (const auto& result : results) {
      std::string line = "prefix";
      append_result_line(line, dump(id), result);
      EXPECT_EQ(line, "prefix" + result_line(id, result));
    }
}

// (protocol.cc's discovery document, tested here where protocol.cc is compiled in)
TEST(JsonRpcOpenRpc, AConcurrentServiceSaysSoAndIsNotInterruptible) {
  ServiceDescriptor sleep;
  sleep.component = "time";
  sleep.name = "sleep";
  sleep.is_async = true;
  sleep.concurrent = true;
  ServiceDescriptor go = sleep;
  go.component = "robot.waypoint";
  go.name = "goto";
  go.concurrent = false;
  const json doc = openrpc_document({sleep, go}, "test", "preempt");
  ASSERT_EQ(doc["methods"].size(), 2u);
  const json& g = doc["methods"][0];  // sorted by name
  const json& s = doc["methods"][1];
  EXPECT_EQ(s["name"], "time.sleep");
  EXPECT_EQ(s["x-concurrent"], true);
  EXPECT_EQ(s["x-interruptible"], false);  // a global preempt policy does not apply to it
  EXPECT_EQ(g["x-concurrent"], false);
  EXPECT_EQ(g["x-interruptible"], true);
}

}  // namespace
}  // namespace simgate::jsonrpc
