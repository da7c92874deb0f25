// The kit's WebSocket frame parser without a socket (simgate/kit/ws_frames.h):
// client frames in any split, the events out, every protocol error. The session's use of it
// on a real socket is in websocket_test.cc (WebSocketTest: raw frames on a socket).
#include "simgate/kit/ws_frames.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace simgate::kit {
namespace {

using P = FrameParser;

// One client frame, masked with `key` (or unmasked), `rsv` in the first byte's bits 4-6.
std::string frame(std::uint8_t opcode, std::string_view payload, bool fin = true,
                  bool masked = true, std::uint8_t rsv = 0, std::uint32_t key = 0x37FA213D) {
  std::string f;
  f.push_back(static_cast<char>((fin ? 0x80 : 0) | (rsv << 4) | opcode));
  const std::uint8_t m = masked ? 0x80 : 0;
  const std::uint64_t n = payload.size();
  if (n < 126) {
    f.push_back(static_cast<char>(m | n));
  } else if (n <= 0xFFFF) {
    f.push_back(static_cast<char>(m | 126));
    f.push_back(static_cast<char>(n >> 8));
    f.push_back(static_cast<char>(n));
  } else {
    f.push_back(static_cast<char>(m | 127));
    for (int i = 0; i < 8; ++i) f.push_back(static_cast<char>(n >> (56 - 8 * i)));
  }
  const unsigned char k[4] = {
      static_cast<unsigned char>(key >> 24), static_cast<unsigned char>(key >> 16),
      static_cast<unsigned char>(key >> 8), static_cast<unsigned char>(key)};
  if (masked) f.append(reinterpret_cast<const char*>(k), 4);
  for (std::size_t i = 0; i < payload.size(); ++i)
    f.push_back(masked ? static_cast<char>(payload[i] ^ k[i & 3]) : payload[i]);
  return f;
}

// A frame header alone announcing `length` (64-bit form), masked.
std::string header64(std::uint8_t opcode, std::uint64_t length, bool fin = true) {
  std::string f;
  f.push_back(static_cast<char>((fin ? 0x80 : 0) | opcode));
  f.push_back(static_cast<char>(0x80 | 127));
  for (int i = 0; i < 8; ++i) f.push_back(static_cast<char>(length >> (56 - 8 * i)));
  f.append("\0\0\0\0", 4);
  return f;
}

// The events as text, one per entry: "text:<message>", "bin:<message>" (a parser that
// delivers binary messages), "refused:<bytes>", "binary:<bytes>" (refused unread),
// "ping:<payload>", "pong:...", "close:...", "error:<reason>".
struct Recorder : FrameSink {
  std::vector<std::string> events;
  void on_text(std::string_view text) override { events.push_back("text:" + std::string(text)); }
  void on_binary(std::string_view data) override { events.push_back("bin:" + std::string(data)); }
  void on_refused(std::size_t bytes, bool binary) override {
    events.push_back((binary ? "binary:" : "refused:") + std::to_string(bytes));
  }
  void on_control(std::uint8_t opcode, std::string_view payload) override {
    const char* name = opcode == P::k_ping ? "ping:" : opcode == P::k_pong ? "pong:" : "close:";
    events.push_back(name + std::string(payload));
  }
  void on_protocol_error(std::string_view reason) override {
    events.push_back("error:" + std::string(reason));
  }
};

std::vector<std::string> parse(std::string_view bytes, std::size_t max = 1 << 20) {
  P parser(max);
  Recorder r;
  parser.feed(bytes, r);
  return r.events;
}

// `bytes` fed in two parts split at `at`, then in parts of one byte
std::vector<std::string> parse_split(std::string_view bytes, std::size_t at,
                                     std::size_t max = 1 << 20) {
  P parser(max);
  Recorder r;
  if (parser.feed(bytes.substr(0, at), r)) parser.feed(bytes.substr(at), r);
  return r.events;
}

std::vector<std::string> parse_bytewise(std::string_view bytes, std::size_t max = 1 << 20) {
  P parser(max);
  Recorder r;
  for (char c : bytes)
    if (!parser.feed(std::string_view(&c, 1), r)) break;
  return r.events;
}

using Events = std::vector<std::string>;

TEST(WebSocketFrames, ATextMessageIsUnmaskedAndDelivered) {
  P parser(1 << 20);
  Recorder r;
  EXPECT_TRUE(parser.feed(frame(P::k_text, "{\"jsonrpc\": \"2.0\"}"), r));
  EXPECT_EQ(r.events, (Events{"text:{\"jsonrpc\": \"2.0\"}"}));
  EXPECT_TRUE(parser.idle());
  EXPECT_EQ(parse(frame(P::k_text, "")), (Events{"text:"}));
}

TEST(WebSocketFrames, ASplitAtEveryByteGivesTheSameEvents) {
  const std::string stream = frame(P::k_text, "hello", false) + frame(P::k_ping, "p1") +
                             frame(P::k_continuation, std::string(300, 'x'), true) +
                             frame(P::k_binary, "bin") + frame(P::k_pong, "") +
                             frame(P::k_text, std::string(70000, 'y')) +
                             frame(P::k_close,
                                   "\x03\xe8"
                                   "bye");
  const Events whole = parse(stream);
  ASSERT_EQ(whole.size(), 6u);
  EXPECT_EQ(whole[0], "ping:p1");
  EXPECT_EQ(whole[1], "text:hello" + std::string(300, 'x'));
  EXPECT_EQ(whole[2], "binary:3");
  EXPECT_EQ(whole[3], "pong:");
  EXPECT_EQ(whole[4], "text:" + std::string(70000, 'y'));
  EXPECT_EQ(whole[5],
            "close:\x03\xe8"
            "bye");
  // every split point of the frames' heads and payloads (the long message's middle, sampled)
  for (std::size_t at = 0; at <= stream.size();
       at += (at < 400 || at + 400 > stream.size()) ? 1 : 997)
    ASSERT_EQ(parse_split(stream, at), whole) << "split at " << at;
  EXPECT_EQ(parse_bytewise(stream), whole);
}

TEST(WebSocketFrames, FragmentsWithControlFramesBetweenThem) {
  const std::string stream = frame(P::k_text, "[1,", false) + frame(P::k_ping, "a") +
                             frame(P::k_continuation, "2,", false) + frame(P::k_pong, "b") +
                             frame(P::k_close, "") + frame(P::k_continuation, "3]", true);
  EXPECT_EQ(parse(stream), (Events{"ping:a", "pong:b", "close:", "text:[1,2,3]"}));
  EXPECT_EQ(parse_bytewise(stream), parse(stream));
  // empty fragments, a fragmented binary message
  EXPECT_EQ(parse(frame(P::k_text, "", false) + frame(P::k_continuation, "", false) +
                  frame(P::k_continuation, "z")),
            (Events{"text:z"}));
  EXPECT_EQ(parse(frame(P::k_binary, "ab", false) + frame(P::k_continuation, "cde")),
            (Events{"binary:5"}));
}

TEST(WebSocketFrames, LengthsAtEachEncodingsEdges) {
  for (std::size_t n : {0u, 1u, 125u, 126u, 127u, 65535u, 65536u, 70001u}) {
    const std::string payload(n, 'q');
    const std::string f = frame(P::k_text, payload);
    EXPECT_EQ(f.size(), n + (n < 126 ? 6 : n <= 0xFFFF ? 8 : 14)) << n;
    EXPECT_EQ(parse(f), (Events{"text:" + payload})) << n;
    EXPECT_EQ(parse_split(f, 3), (Events{"text:" + payload})) << n;
  }
  // the 16- and 64-bit forms may carry small lengths too (not minimal: still accepted)
  std::string f = "\x81\xfe";
  f += std::string("\x00\x03", 2) + std::string("\0\0\0\0", 4) + "abc";
  EXPECT_EQ(parse(f), (Events{"text:abc"}));
  EXPECT_EQ(parse(header64(P::k_text, 2) + "hi"), (Events{"text:hi"}));
}

TEST(WebSocketFrames, AnUnmaskedFrameIsAProtocolError) {
  EXPECT_EQ(parse(frame(P::k_text, "x", true, false)),
            (Events{"error:an unmasked frame (a client masks every frame)"}));
  EXPECT_EQ(parse(frame(P::k_ping, "", true, false)),
            (Events{"error:an unmasked frame (a client masks every frame)"}));
}

TEST(WebSocketFrames, ReservedBitsAreAProtocolError) {
  for (std::uint8_t rsv : {1, 2, 4, 7})
    EXPECT_EQ(parse(frame(P::k_text, "x", true, true, rsv)),
              (Events{"error:reserved bits set (no extension was agreed)"}))
        << int(rsv);
}

TEST(WebSocketFrames, ReservedOpcodesAreAProtocolError) {
  for (std::uint8_t op : {0x3, 0x4, 0x5, 0x6, 0x7, 0xB, 0xC, 0xD, 0xE, 0xF})
    EXPECT_EQ(parse(frame(op, "")), (Events{"error:a reserved opcode"})) << int(op);
}

TEST(WebSocketFrames, LongOrFragmentedControlFramesAreAProtocolError) {
  EXPECT_EQ(parse(frame(P::k_ping, std::string(125, 'p'))),
            (Events{"ping:" + std::string(125, 'p')}));
  EXPECT_EQ(parse(frame(P::k_ping, std::string(126, 'p'))),
            (Events{"error:a fragmented or long control frame"}));
  EXPECT_EQ(parse(frame(P::k_close, "", false)),
            (Events{"error:a fragmented or long control frame"}));
  EXPECT_EQ(parse(frame(P::k_text, "a", false) + frame(P::k_pong, "", false)),
            (Events{"error:a fragmented or long control frame"}));
}

TEST(WebSocketFrames, AContinuationWithoutAMessageIsAProtocolError) {
  EXPECT_EQ(parse(frame(P::k_continuation, "x")),
            (Events{"error:a continuation frame with no message"}));
  EXPECT_EQ(parse(frame(P::k_text, "a") + frame(P::k_continuation, "b")),
            (Events{"text:a", "error:a continuation frame with no message"}));
}

TEST(WebSocketFrames, ANewMessageInsideAFragmentedOneIsAProtocolError) {
  EXPECT_EQ(parse(frame(P::k_text, "a", false) + frame(P::k_text, "b")),
            (Events{"error:a new message inside a fragmented one"}));
  EXPECT_EQ(parse(frame(P::k_binary, "a", false) + frame(P::k_ping, "") + frame(P::k_binary, "b")),
            (Events{"ping:", "error:a new message inside a fragmented one"}));
}

TEST(WebSocketFrames, ALengthOver2Pow63IsAProtocolError) {
  EXPECT_EQ(parse(header64(P::k_text, std::uint64_t{1} << 63)),
            (Events{"error:a frame length over 2^63"}));
}

TEST(WebSocketFrames, NothingIsParsedAfterAProtocolError) {
  P parser(1 << 20);
  Recorder r;
  EXPECT_FALSE(parser.feed(frame(P::k_text, "x", true, false) + frame(P::k_text, "y"), r));
  EXPECT_TRUE(parser.failed());
  EXPECT_EQ(parser.error(), "an unmasked frame (a client masks every frame)");
  EXPECT_FALSE(parser.feed(frame(P::k_text, "z"), r));
  EXPECT_EQ(r.events, (Events{"error:an unmasked frame (a client masks every frame)"}));
}

TEST(WebSocketFrames, AnOversizedMessageIsSkippedAndTheNextOneRead) {
  const std::size_t max = 100;
  EXPECT_EQ(parse(frame(P::k_text, std::string(100, 'a')), max),
            (Events{"text:" + std::string(100, 'a')}));
  const std::string stream = frame(P::k_text, std::string(60, 'a'), false) + frame(P::k_ping, "!") +
                             frame(P::k_continuation, std::string(60, 'b')) +
                             frame(P::k_text, "next") + frame(P::k_text, std::string(101, 'c')) +
                             frame(P::k_text, "last");
  const Events expected{"ping:!", "refused:120", "text:next", "refused:101", "text:last"};
  EXPECT_EQ(parse(stream, max), expected);
  EXPECT_EQ(parse_bytewise(stream, max), expected);
  // a huge announced length: skipped as it arrives, never buffered
  P parser(max);
  Recorder r;
  EXPECT_TRUE(parser.feed(header64(P::k_text, 10'000'000), r));
  const std::string chunk(64 * 1024, 'z');
  std::size_t sent = 0;
  while (sent + chunk.size() <= 10'000'000) {
    ASSERT_TRUE(parser.feed(chunk, r));
    sent += chunk.size();
  }
  EXPECT_LE(parser.buffer_capacity(), P::k_keep_bytes);
  EXPECT_TRUE(parser.feed(std::string(10'000'000 - sent, 'z') + frame(P::k_text, "after"), r));
  EXPECT_EQ(r.events, (Events{"refused:10000000", "text:after"}));
}

// Found by the fuzz target's reference reader, which said "binary" first: the session has
// always answered a binary message over the limit as too large (kept, unchanged).
TEST(WebSocketFrames, ABinaryMessageOverTheLimitIsRefusedAsTooLong) {
  EXPECT_EQ(parse(frame(P::k_binary, "ab"), 1), (Events{"refused:2"}));
  EXPECT_EQ(parse(frame(P::k_binary, "a", false) + frame(P::k_continuation, "b"), 1),
            (Events{"refused:2"}));
  EXPECT_EQ(parse(frame(P::k_binary, "a"), 1), (Events{"binary:1"}));
}

TEST(WebSocketFrames, ALargeMessageBufferIsNotKept) {
  P parser(8 << 20);
  Recorder r;
  parser.feed(frame(P::k_text, std::string(1 << 20, 'm')), r);
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_LE(parser.buffer_capacity(), P::k_keep_bytes);
}

// a sink that discards messages after its first event, or stops the parser
struct Closer : Recorder {
  P* parser = nullptr;
  bool stop = false;
  void on_control(std::uint8_t opcode, std::string_view payload) override {
    Recorder::on_control(opcode, payload);
    if (stop)
      parser->stop();
    else
      parser->discard_messages();
  }
};

TEST(WebSocketFrames, DiscardedMessagesAreParsedButNotReported) {
  P parser(1 << 20);
  Closer c;
  c.parser = &parser;
  EXPECT_TRUE(parser.feed(frame(P::k_text, "a", false) + frame(P::k_close, "\x03\xe8") +
                              frame(P::k_continuation, "b") + frame(P::k_text, "c") +
                              frame(P::k_ping, "p"),
                          c));
  EXPECT_EQ(c.events, (Events{"close:\x03\xe8", "ping:p"}));
  EXPECT_FALSE(parser.feed(frame(P::k_text, "x", true, false), c));  // errors still count
}

TEST(WebSocketFrames, StopEndsParsingAtOnce) {
  P parser(1 << 20);
  Closer c;
  c.parser = &parser;
  c.stop = true;
  EXPECT_FALSE(
      parser.feed(frame(P::k_ping, "1") + frame(P::k_text, "a") + frame(P::k_ping, "2"), c));
  EXPECT_EQ(c.events, (Events{"ping:1"}));
  EXPECT_FALSE(parser.failed());
}

TEST(WebSocketFrames, BinaryMessagesAreDeliveredWhenAskedFor) {
  // a protocol with binary messages (Foxglove's): fragmented or not, within the limit, as
  // text ones are; over it, skipped and reported as too long
  P parser(16, /*binary_messages=*/true);
  Recorder r;
  const std::string stream = frame(P::k_binary,
                                   std::string("\x02\x00"
                                               "ab",
                                               4),
                                   false) +
                             frame(P::k_ping, "p") + frame(P::k_continuation, "cd", true) +
                             frame(P::k_binary, std::string(17, 'z')) + frame(P::k_text, "t");
  EXPECT_TRUE(parser.feed(stream, r));
  EXPECT_EQ(r.events, (Events{"ping:p",
                              "bin:" + std::string("\x02\x00"
                                                   "abcd",
                                                   6),
                              "refused:17", "text:t"}));
  // without asking, the same bytes are refused unread
  EXPECT_EQ(parse(frame(P::k_binary, "abc")), (Events{"binary:3"}));
}

}  // namespace
}  // namespace simgate::kit
