// Fuzz target websocket_frames: what a WebSocket client's bytes go through once upgraded
// (simgate/kit/ws_frames.h, FrameParser: what kit::WebSocketConnection feeds each read to).
//
// Input: byte 0 and 1 seed the split sizes (0 to 2 * (1 + byte 1 % 64) bytes per feed, empty
// feeds included; byte 1 == 255: the whole stream in one feed), byte 2 picks
// max_message_bytes (0..254, or 255: the transport's default 8 MiB), byte 3 the event after
// which the sink calls discard_messages() (0: never; what a closing session does); the rest
// is the stream.
//
// Properties: the events are those of a reference reader written as simply as possible
// (the whole stream at once, frame by frame), reasons included; they do not depend on the
// split (seeded splits, byte by byte: the same events as one feed); a text message is at most max_message_bytes; a message
// refused as too long is longer than that; a control frame is a close, ping or pong of at
// most 125 bytes; the payloads delivered never exceed the stream; after a protocol error
// (or once stopped) there is no event and feed() returns false; no data message is reported
// after discard_messages(); the message buffer stays bounded.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.h"
#include "simgate/kit/ws_frames.h"

namespace simgate::fuzz {
namespace {

using kit::FrameParser;
using kit::FrameSink;

struct Event {
  char kind;  // 't' text, 'B' binary, 'r' too long, 'b' binary refused, 'c' control, 'e' error
  std::uint8_t opcode = 0;
  std::size_t bytes = 0;
  std::string payload;
  bool operator==(const Event&) const = default;
};

struct Recorder : FrameSink {
  FrameParser* parser = nullptr;
  std::size_t max_message_bytes = 0;
  bool binary_messages = false;   // the parser delivers binary messages
  std::size_t discard_after = 0;  // 0: never
  std::vector<Event> events;
  bool failed = false;
  bool discarding = false;
  std::size_t payload_bytes = 0;  // delivered text and control payloads

  void event(Event e) {
    FUZZ_CHECK(!failed, "no event after a protocol error");
    FUZZ_CHECK(!parser->stopped() || e.kind == 'e', "no event from a stopped parser");
    events.push_back(std::move(e));
    if (discard_after != 0 && events.size() == discard_after) {
      parser->discard_messages();
      discarding = true;
    }
  }
  void on_text(std::string_view text) override {
    FUZZ_CHECK(!discarding, "no message after discard_messages()");
    FUZZ_CHECK(text.size() <= max_message_bytes, "a text message is at most max_message_bytes");
    payload_bytes += text.size();
    event({'t', 0, text.size(), std::string(text)});
  }
  void on_binary(std::string_view data) override {
    FUZZ_CHECK(!discarding, "no message after discard_messages()");
    FUZZ_CHECK(binary_messages, "binary messages are delivered only when asked for");
    FUZZ_CHECK(data.size() <= max_message_bytes, "a binary message is at most max_message_bytes");
    payload_bytes += data.size();
    event({'B', 0, data.size(), std::string(data)});
  }
  void on_refused(std::size_t bytes, bool binary) override {
    FUZZ_CHECK(!discarding, "no message after discard_messages()");
    FUZZ_CHECK(!binary || !binary_messages, "binary messages are refused only when not asked for");
    FUZZ_CHECK(binary || bytes > max_message_bytes,
               "a message refused as too long is longer than the limit");
    event({binary ? 'b' : 'r', 0, bytes, {}});
  }
  void on_control(std::uint8_t opcode, std::string_view payload) override {
    FUZZ_CHECK(opcode == FrameParser::k_close || opcode == FrameParser::k_ping ||
                   opcode == FrameParser::k_pong,
               "a control frame is a close, ping or pong");
    FUZZ_CHECK(payload.size() <= 125, "a control frame's payload is at most 125 bytes");
    payload_bytes += payload.size();
    event({'c', opcode, payload.size(), std::string(payload)});
  }
  void on_protocol_error(std::string_view reason) override {
    FUZZ_CHECK(!reason.empty(), "a protocol error has a reason");
    FUZZ_CHECK(parser->failed() && parser->error() == reason,
               "the parser keeps the error's reason");
    event({'e', 0, 0, std::string(reason)});
    failed = true;
  }
};

// The events, one a line, for a failed property's report.
void print(const char* title, const std::vector<Event>& events) {
  std::fprintf(stderr, "%s:\n", title);
  for (const Event& e : events)
    std::fprintf(stderr, "  %c opcode %u bytes %zu payload %zu\n", e.kind, unsigned{e.opcode},
                 e.bytes, e.payload.size());
}

// Checks that `got` are the `expected` events, printing both if not.
void expect_events(const std::vector<Event>& got, const std::vector<Event>& expected,
                   const char* what) {
  if (got == expected) return;
  print("expected", expected);
  print("got", got);
  FUZZ_CHECK(false, what);
}

// A small deterministic generator for the split sizes (xorshift32).
struct Splits {
  std::uint32_t state;
  std::size_t spread;
  std::size_t next() {
    state ^= state << 13;
    state ^= state >> 17;
    state ^= state << 5;
    return state % (2 * spread + 1);
  }
};

// The reference: RFC 6455 read straight from the whole stream, frame by frame, as simply as
// it can be written (no state across feeds). The events FrameParser must report for the
// stream; what an incomplete last frame would need is simply not reached.
std::vector<Event> reference(std::string_view stream, std::size_t max, std::size_t discard_after,
                             bool binary_messages) {
  std::vector<Event> events;
  bool discard = false;
  const auto emit = [&](Event e) {
    events.push_back(std::move(e));
    if (discard_after != 0 && events.size() == discard_after) discard = true;
  };
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(stream[i]); };
  bool in_message = false, binary = false;
  std::string text;
  std::size_t total = 0;
  std::size_t at = 0;
  for (;;) {
    const std::size_t left = stream.size() - at;
    if (left < 2) break;
    const unsigned char b0 = byte(at), b1 = byte(at + 1);
    const bool fin = b0 & 0x80;
    const unsigned op = b0 & 0x0F;
    if (b0 & 0x70) {
      emit({'e', 0, 0, "reserved bits set (no extension was agreed)"});
      break;
    }
    if (!(b1 & 0x80)) {
      emit({'e', 0, 0, "an unmasked frame (a client masks every frame)"});
      break;
    }
    const unsigned len7 = b1 & 0x7F;
    const std::size_t ext = len7 == 126 ? 2 : len7 == 127 ? 8 : 0;
    if (left < 2 + ext + 4) break;
    std::uint64_t length = len7;
    if (ext > 0) {
      length = 0;
      for (std::size_t i = 0; i < ext; ++i) length = length * 256 + byte(at + 2 + i);
    }
    if (length >= (std::uint64_t{1} << 63)) {
      emit({'e', 0, 0, "a frame length over 2^63"});
      break;
    }
    const std::size_t key_at = at + 2 + ext, payload_at = key_at + 4;
    const std::size_t here = stream.size() - payload_at;  // payload bytes present
    const auto unmask = [&](std::size_t i) {
      return static_cast<char>(byte(payload_at + i) ^ byte(key_at + i % 4));
    };
    if (op >= 8) {
      if (!fin || length > 125) {
        emit({'e', 0, 0, "a fragmented or long control frame"});
        break;
      }
      if (op != 8 && op != 9 && op != 10) {
        emit({'e', 0, 0, "a reserved opcode"});
        break;
      }
      if (here < length) break;
      std::string payload;
      for (std::size_t i = 0; i < length; ++i) payload.push_back(unmask(i));
      emit({'c', static_cast<std::uint8_t>(op), payload.size(), payload});
      at = payload_at + length;
      continue;
    }
    if (op > 2) {
      emit({'e', 0, 0, "a reserved opcode"});
      break;
    }
    if (op == 0 && !in_message) {
      emit({'e', 0, 0, "a continuation frame with no message"});
      break;
    }
    if (op != 0 && in_message) {
      emit({'e', 0, 0, "a new message inside a fragmented one"});
      break;
    }
    if (op != 0) {
      in_message = true;
      binary = op == 2;
      text.clear();
      total = 0;
    }
    const std::size_t take = static_cast<std::size_t>(std::min<std::uint64_t>(length, here));
    for (std::size_t i = 0; i < take; ++i) text.push_back(unmask(i));
    total += take;
    if (take < length) break;  // the stream ends inside this frame
    at = payload_at + take;
    if (!fin) continue;
    in_message = false;
    if (discard) continue;
    if (total >
        max)  // too long first, binary or not (the session's answer since before the parser)
      emit({'r', 0, total, {}});
    else if (binary && binary_messages)
      emit({'B', 0, total, text});
    else if (binary)
      emit({'b', 0, total, {}});
    else
      emit({'t', 0, total, text});
  }
  return events;
}

// Feeds `stream` to a fresh parser, in one feed or in splits; checks what does not depend on
// the split and returns the events.
std::vector<Event> run(std::string_view stream, std::size_t max, std::size_t discard_after,
                       bool binary_messages, Splits* splits) {
  FrameParser parser(max, binary_messages);
  Recorder r;
  r.parser = &parser;
  r.max_message_bytes = max;
  r.binary_messages = binary_messages;
  r.discard_after = discard_after;
  bool going = true;
  std::size_t at = 0;
  if (!splits) {
    going = parser.feed(stream, r);
  } else {
    while (going && at < stream.size()) {
      const std::size_t n = std::min(splits->next(), stream.size() - at);
      going = parser.feed(stream.substr(at, n), r);
      at += n;
    }
    if (going) going = parser.feed({}, r);  // an empty feed changes nothing
  }
  FUZZ_CHECK(going == !parser.stopped(), "feed() is false exactly when the parser stopped");
  FUZZ_CHECK(going == !r.failed, "only a protocol error stops the parser here");
  FUZZ_CHECK(r.payload_bytes <= stream.size(), "payloads delivered never exceed the stream");
  FUZZ_CHECK(parser.buffer_capacity() <=
                 std::max<std::size_t>(FrameParser::k_keep_bytes, stream.size() + 64),
             "the message buffer is bounded");
  if (!going) {
    // nothing more once stopped, not even a whole valid frame
    const std::size_t before = r.events.size();
    const char text_frame[] = {'\x81', '\x80', 0, 0, 0, 0};
    FUZZ_CHECK(!parser.feed(std::string_view(text_frame, sizeof text_frame), r),
               "a stopped parser stays stopped");
    FUZZ_CHECK(r.events.size() == before, "a stopped parser reports nothing");
  }
  return r.events;
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate::fuzz;
  if (size < 4) return 0;
  const std::size_t max = data[2] == 255 ? std::size_t{8} << 20 : data[2];
  const std::size_t discard_after = data[3];
  const std::string_view stream(reinterpret_cast<const char*>(data + 4), size - 4);
  const bool binary_messages = data[0] & 1;  // a parser that delivers binary messages too

  const std::vector<Event> whole = run(stream, max, discard_after, binary_messages, nullptr);
  expect_events(whole, reference(stream, max, discard_after, binary_messages),
                "the events are the reference reader's");
  if (data[1] != 255) {
    Splits splits{(std::uint32_t{data[0]} << 8 | data[1]) * 2654435761u | 1u, 1u + data[1] % 64u};
    const std::vector<Event> split = run(stream, max, discard_after, binary_messages, &splits);
    expect_events(split, whole, "the events do not depend on how the stream is split");
  }
  // one byte at a time, the finest split
  if (stream.size() <= 4096) {
    FrameParser parser(max, binary_messages);
    Recorder r;
    r.parser = &parser;
    r.max_message_bytes = max;
    r.binary_messages = binary_messages;
    r.discard_after = discard_after;
    for (char c : stream)
      if (!parser.feed(std::string_view(&c, 1), r)) break;
    expect_events(r.events, whole,
                  "the events do not depend on how the stream is split (byte by byte)");
  }
  return 0;
}
