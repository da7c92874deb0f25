// Fuzz target websocket_frames: what a WebSocket client's bytes go through once upgraded
// (plugins/websocket/ws_frames.h, FrameParser: what WsSession feeds each read to).
//
// Input: byte 0 and 1 seed the split sizes (0 to 2 * (1 + byte 1 % 64) bytes per feed, empty
// feeds included; byte 1 == 255: the whole stream in one feed), byte 2 picks
// max_message_bytes (0..254, or 255: the transport's default 8 MiB), byte 3 the event after
// which the sink calls discard_messages() (0: never; what a closing session does); the rest
// is the stream.
//
// Properties: the events do not depend on the split (the same stream fed at once gives the
// same events, reasons included); a text message is at most max_message_bytes; a message
// refused as too long is longer than that; a control frame is a close, ping or pong of at
// most 125 bytes; the payloads delivered never exceed the stream; after a protocol error
// (or once stopped) there is no event and feed() returns false; no data message is reported
// after discard_messages(); the message buffer stays bounded.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.h"
#include "ws_frames.h"

namespace simgate::fuzz {
namespace {

using websocket::FrameParser;
using websocket::FrameSink;

struct Event {
  char kind;  // 't' text, 'r' too long, 'b' binary, 'c' control, 'e' protocol error
  std::uint8_t opcode = 0;
  std::size_t bytes = 0;
  std::string payload;
  bool operator==(const Event&) const = default;
};

struct Recorder : FrameSink {
  FrameParser* parser = nullptr;
  std::size_t max_message_bytes = 0;
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
  void on_refused(std::size_t bytes, bool binary) override {
    FUZZ_CHECK(!discarding, "no message after discard_messages()");
    FUZZ_CHECK(binary || bytes > max_message_bytes, "a message refused as too long is longer than the limit");
    event({binary ? 'b' : 'r', 0, bytes, {}});
  }
  void on_control(std::uint8_t opcode, std::string_view payload) override {
    FUZZ_CHECK(opcode == FrameParser::k_close || opcode == FrameParser::k_ping || opcode == FrameParser::k_pong,
               "a control frame is a close, ping or pong");
    FUZZ_CHECK(payload.size() <= 125, "a control frame's payload is at most 125 bytes");
    payload_bytes += payload.size();
    event({'c', opcode, payload.size(), std::string(payload)});
  }
  void on_protocol_error(std::string_view reason) override {
    FUZZ_CHECK(!reason.empty(), "a protocol error has a reason");
    FUZZ_CHECK(parser->failed() && parser->error() == reason, "the parser keeps the error's reason");
    event({'e', 0, 0, std::string(reason)});
    failed = true;
  }
};

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

// Feeds `stream` to a fresh parser, in one feed or in splits; checks what does not depend on
// the split and returns the events.
std::vector<Event> run(std::string_view stream, std::size_t max, std::size_t discard_after, Splits* splits) {
  FrameParser parser(max);
  Recorder r;
  r.parser = &parser;
  r.max_message_bytes = max;
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
  FUZZ_CHECK(parser.buffer_capacity() <= std::max<std::size_t>(FrameParser::k_keep_bytes, stream.size() + 64),
             "the message buffer is bounded");
  if (!going) {
    // nothing more once stopped, not even a whole valid frame
    const std::size_t before = r.events.size();
    const char text_frame[] = {'\x81', '\x80', 0, 0, 0, 0};
    FUZZ_CHECK(!parser.feed(std::string_view(text_frame, sizeof text_frame), r), "a stopped parser stays stopped");
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

  const std::vector<Event> whole = run(stream, max, discard_after, nullptr);
  if (data[1] != 255) {
    Splits splits{(std::uint32_t{data[0]} << 8 | data[1]) * 2654435761u | 1u, 1u + data[1] % 64u};
    const std::vector<Event> split = run(stream, max, discard_after, &splits);
    FUZZ_CHECK(split == whole, "the events do not depend on how the stream is split");
  }
  // one byte at a time, the finest split
  if (stream.size() <= 4096) {
    FrameParser parser(max);
    Recorder r;
    r.parser = &parser;
    r.max_message_bytes = max;
    r.discard_after = discard_after;
    for (char c : stream)
      if (!parser.feed(std::string_view(&c, 1), r)) break;
    FUZZ_CHECK(r.events == whole, "the events do not depend on how the stream is split (byte by byte)");
  }
  return 0;
}
