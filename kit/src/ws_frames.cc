#include "simgate/kit/ws_frames.h"

#include <algorithm>
#include <cstring>

namespace simgate::kit {

bool FrameParser::feed(std::string_view bytes, FrameSink& sink) {
  const char* p = bytes.data();
  const char* const end = p + bytes.size();
  while (!stopped_) {
    if (!in_frame_) {
      // a frame's head: 2 bytes, the extended length (0, 2 or 8), the masking key (4), and
      // a control frame's payload
      std::size_t size = 0, header = 0;
      Head head;
      const unsigned char* frame;
      if (head_size_ > 0) {
        // one begun in an earlier feed: completed from these bytes, exactly to its size
        for (;;) {
          head = read_head(head_, head_size_, size, header, sink);
          if (head != Head::more) break;
          if (p == end) return true;
          const std::size_t n = std::min<std::size_t>(size - head_size_, end - p);
          std::memcpy(head_ + head_size_, p, n);
          head_size_ += n;
          p += n;
        }
        frame = head_;
        head_size_ = 0;
      } else {
        const auto* h = reinterpret_cast<const unsigned char*>(p);
        head = read_head(h, end - p, size, header, sink);
        if (head == Head::more) {  // kept for the next feed (shorter than k_max_head_bytes)
          head_size_ = end - p;
          if (head_size_ > 0) std::memcpy(head_, p, head_size_);
          return true;
        }
        frame = h;
        if (head != Head::error) p += size;
      }
      if (head == Head::error) return false;
      if (head == Head::control) {
        control(frame, header, size, sink);
        continue;
      }
    }
    // a data frame's payload, as much as is here
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(frame_left_, end - p));
    message_bytes_ += n;
    if (!skipping_ && message_bytes_ > max_message_bytes_) {
      // too long: skipped to its end (reported then), never buffered
      skipping_ = true;
      message_.clear();
      if (message_.capacity() > k_keep_bytes) std::string().swap(message_);
    }
    if (!skipping_ && (!message_binary_ || binary_messages_) && !discard_) {
      const std::size_t at = message_.size();
      message_.resize(at + n);
      char* out = message_.data() + at;
      for (std::size_t i = 0; i < n; ++i)
        out[i] = static_cast<char>(p[i] ^ mask_[(mask_at_ + i) & 3]);
    }
    mask_at_ += n;
    p += n;
    frame_left_ -= n;
    if (frame_left_ > 0) return true;  // the rest comes with the next feed
    in_frame_ = false;
    if (frame_fin_) end_message(sink);
  }
  return false;
}

FrameParser::Head FrameParser::read_head(const unsigned char* h, std::size_t avail,
                                         std::size_t& size, std::size_t& header, FrameSink& sink) {
  if (avail < 2) {
    size = 2;
    return Head::more;
  }
  const bool fin = h[0] & 0x80;
  const std::uint8_t opcode = h[0] & 0x0F;
  const std::uint8_t length7 = h[1] & 0x7F;
  if (h[0] & 0x70) return fail("reserved bits set (no extension was agreed)", sink);
  if (!(h[1] & 0x80)) return fail("an unmasked frame (a client masks every frame)", sink);
  header = 2 + (length7 == 126 ? 2 : length7 == 127 ? 8 : 0) + 4;
  if (avail < header) {
    size = header;
    return Head::more;
  }
  std::uint64_t length = length7;
  if (length7 == 126) {
    length = (std::uint64_t{h[2]} << 8) | h[3];
  } else if (length7 == 127) {
    length = 0;
    for (int i = 0; i < 8; ++i) length = (length << 8) | h[2 + i];
    if (length >> 63) return fail("a frame length over 2^63", sink);
  }
  if (opcode >= 0x8) {
    // a control frame: whole, at most 125 bytes, handled once it is all here
    if (!fin || length > 125) return fail("a fragmented or long control frame", sink);
    if (opcode != k_close && opcode != k_ping && opcode != k_pong)
      return fail("a reserved opcode", sink);
    size = header + static_cast<std::size_t>(length);
    return avail < size ? Head::more : Head::control;
  }
  if (opcode > k_binary) return fail("a reserved opcode", sink);
  if (opcode == k_continuation && !in_message_)
    return fail("a continuation frame with no message", sink);
  if (opcode != k_continuation && in_message_)
    return fail("a new message inside a fragmented one", sink);
  // a data frame begins
  if (opcode != k_continuation) {
    in_message_ = true;
    message_binary_ = opcode == k_binary;
    message_bytes_ = 0;
    skipping_ = false;
    message_.clear();
  }
  std::memcpy(mask_, h + header - 4, 4);
  mask_at_ = 0;
  frame_fin_ = fin;
  frame_left_ = length;
  in_frame_ = true;
  size = header;
  return Head::data;
}

void FrameParser::control(const unsigned char* frame, std::size_t header, std::size_t size,
                          FrameSink& sink) {
  char payload[125];
  const std::size_t length = size - header;
  const unsigned char* key = frame + header - 4;
  for (std::size_t i = 0; i < length; ++i)
    payload[i] = static_cast<char>(frame[header + i] ^ key[i & 3]);
  sink.on_control(frame[0] & 0x0F, std::string_view(payload, length));
}

void FrameParser::end_message(FrameSink& sink) {
  in_message_ = false;
  if (!discard_) {
    if (skipping_)
      sink.on_refused(message_bytes_, false);
    else if (!message_binary_)
      sink.on_text(message_);
    else if (binary_messages_)
      sink.on_binary(message_);
    else
      sink.on_refused(message_bytes_, true);
  }
  skipping_ = false;
  message_.clear();
  if (message_.capacity() > k_keep_bytes) std::string().swap(message_);  // keep no large buffer
}

FrameParser::Head FrameParser::fail(std::string_view reason, FrameSink& sink) {
  stopped_ = true;
  error_ = reason;
  sink.on_protocol_error(reason);
  return Head::error;
}

}  // namespace simgate::kit
