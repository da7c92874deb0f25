// simgate/kit/ws_frames.h — the reader of RFC 6455 client frames, without a socket: bytes
// in, events out (what kit::WebSocketConnection does with a read; fuzzed by
// tests/fuzz/websocket_frames.cc).
//
// Terms: a message is one data frame, or a text/binary frame and its continuation frames up
// to the one with FIN; control frames (close, ping, pong) may come between its fragments.
//
//   - feed() takes any part of the stream, split anywhere (a header across two reads, one
//     byte at a time); it parses all of it and keeps no byte but the start of a header that
//     is not whole yet (and a control frame not whole yet): at most k_max_head_bytes, in a
//     small array. A data frame's payload is unmasked straight from the caller's bytes into
//     the message (one copy: the unmasking), never buffered elsewhere.
//   - Events, on the FrameSink, in stream order, during feed():
//       on_text       a whole text message (a view of the parser's buffer: valid during the
//                     call); at most max_message_bytes long. UTF-8 is not checked here.
//       on_binary     a whole binary message, for a parser made with binary_messages
//                     (as on_text: a view valid during the call, at most max_message_bytes).
//       on_refused    a message that is not delivered: longer than max_message_bytes
//                     (skipped to its end as it arrives, never buffered; `bytes` arrived in
//                     all; a binary one too, reported as too long) or else binary, for a
//                     parser made without binary_messages (`binary`, never buffered either).
//       on_control    a close, ping or pong frame, unmasked, at most 125 bytes, as soon as
//                     it is whole. What a close payload means (a one-byte one is an error) is
//                     the caller's.
//       on_protocol_error  the stream breaks RFC 6455 (the reason, for logs and the close
//                     frame): an unmasked frame, reserved bits (no extension is agreed), a
//                     reserved opcode, a length over 2^63, a control frame fragmented or over
//                     125 bytes, a continuation with no message, a new message inside a
//                     fragmented one. It ends the parser: failed(), nothing more is parsed.
//   - A sink may call stop() (no more events, the rest of the bytes ignored) or
//     discard_messages() (data messages still parsed but neither buffered nor reported:
//     a connection that is closing) from inside an event.
//
// Life cycle: one parser per connection, for its whole life. Threads: not thread-safe; the
// session's I/O thread uses it.
#ifndef SIMGATE_KIT_WS_FRAMES_H_
#define SIMGATE_KIT_WS_FRAMES_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace simgate::kit {

// What a FrameParser reports (its owner implements it).
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  // One whole text message (`text` lives until the call returns).
  virtual void on_text(std::string_view text) = 0;
  // One whole binary message (a parser made with binary_messages only; `data` lives until
  // the call returns).
  virtual void on_binary(std::string_view data) = 0;
  // A message longer than max_message_bytes (`bytes` in all; `binary` false even for a
  // binary one), or else a binary one (`binary`).
  virtual void on_refused(std::size_t bytes, bool binary) = 0;
  // A control frame: FrameParser::k_close, k_ping or k_pong, and its unmasked payload.
  virtual void on_control(std::uint8_t opcode, std::string_view payload) = 0;
  // The stream breaks the protocol: the parser stops (close the connection with 1002).
  virtual void on_protocol_error(std::string_view reason) = 0;
};

class FrameParser {
 public:
  // RFC 6455 opcodes
  static constexpr std::uint8_t k_continuation = 0x0, k_text = 0x1, k_binary = 0x2, k_close = 0x8,
                                k_ping = 0x9, k_pong = 0xA;
  // The longest frame head kept between two feeds: a header (2 + 8 + 4) and a control
  // frame's payload (125).
  static constexpr std::size_t k_max_head_bytes = 14 + 125;
  // A message buffer larger than this is freed after its message (no large buffer is kept).
  static constexpr std::size_t k_keep_bytes = 256 * 1024;

  // `binary_messages`: binary messages are delivered (on_binary) as text ones are, rather
  // than refused unread.
  explicit FrameParser(std::size_t max_message_bytes, bool binary_messages = false)
      : max_message_bytes_(max_message_bytes), binary_messages_(binary_messages) {}

  // Parses `bytes`, the stream's next part, reporting to `sink`. False once the parser has
  // stopped (a protocol error, or stop()): the rest of the bytes were not parsed, and no
  // later call parses any.
  bool feed(std::string_view bytes, FrameSink& sink);
  // No more parsing: feed() ignores what it is given.
  void stop() { stopped_ = true; }
  // Data messages are no longer buffered or reported (control frames still are).
  void discard_messages() {
    discard_ = true;
    std::string().swap(message_);  // what was received of the current one is let go
  }

  bool stopped() const { return stopped_; }
  // A protocol error stopped it (error() is its reason).
  bool failed() const { return !error_.empty(); }
  const std::string& error() const { return error_; }
  // Between messages: no data frame begun, no frame head kept.
  bool idle() const { return !in_message_ && !in_frame_ && head_size_ == 0; }
  // The bytes of the message being received that are kept (0 between messages, and while
  // one is skipped or discarded).
  std::size_t message_bytes_held() const { return message_.size(); }
  // The message buffer's capacity (bounded: k_keep_bytes once a message ends).
  std::size_t buffer_capacity() const { return message_.capacity(); }

 private:
  enum class Head { more, error, data, control };
  // Reads the frame head at `h` (`avail` bytes). more: `size` bytes are needed; error:
  // reported; data: a data frame's header of `size` bytes (the frame begins); control: a
  // control frame of `size` bytes, whole (`header` of them the header).
  Head read_head(const unsigned char* h, std::size_t avail, std::size_t& size, std::size_t& header,
                 FrameSink& sink);
  void control(const unsigned char* frame, std::size_t header, std::size_t size, FrameSink& sink);
  void end_message(FrameSink& sink);
  Head fail(std::string_view reason, FrameSink& sink);

  std::size_t max_message_bytes_;              // the longest message delivered
  bool binary_messages_;                       // binary messages are delivered too
  unsigned char head_[k_max_head_bytes] = {};  // a frame head begun in an earlier feed...
  std::size_t head_size_ = 0;                  // ...of this many bytes (0: none)
  bool in_frame_ = false;          // a data frame's header was parsed, its payload comes
  bool frame_fin_ = false;         // that frame ends its message
  std::uint64_t frame_left_ = 0;   // payload bytes of that frame still to come
  unsigned char mask_[4] = {};     // that frame's masking key
  std::size_t mask_at_ = 0;        // payload bytes of that frame unmasked so far
  bool in_message_ = false;        // a message began (its first frame was read)
  bool message_binary_ = false;    // that message is binary
  std::string message_;            // that message so far (delivered ones, within max_message_bytes)
  std::size_t message_bytes_ = 0;  // its length so far, skipped or binary included
  bool skipping_ = false;          // it is over max_message_bytes: skipped to its end
  bool discard_ = false;           // discard_messages() was called
  bool stopped_ = false;           // stop() or a protocol error
  std::string error_;              // the protocol error's reason
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_WS_FRAMES_H_
