#include "simgate/kit/line_connection.h"

#include <algorithm>

#include "simgate/core/log.h"

namespace simgate::kit {

namespace {
// How much of an oversized line the host sees (enough for the client's id).
constexpr std::size_t k_oversized_prefix = 1024;

// Only ' ', '\t' and '\r' (or nothing): a loop that ends at a request's first byte, where
// find_first_not_of called memchr on the set for each byte.
bool is_blank(std::string_view line) {
  for (const char c : line)
    if (c != ' ' && c != '\t' && c != '\r') return false;
  return true;
}
}  // namespace

bool LineConnection::grow_line(std::string_view data) {
  if (!held().fits(data.size())) {
    log::warning(who_, ": ", label_,
                 " disconnected: its unfinished line would take the transport past ", held().max(),
                 " bytes held for all connections (max_buffered_bytes)");
    close("max_buffered_bytes reached");
    return false;
  }
  if (partial_.empty()) message_begun();
  partial_.append(data);
  set_framing_bytes(partial_.size());
  return true;
}

std::string LineConnection::take_line(std::string_view end) {
  set_framing_bytes(0);
  partial_.append(end);
  // freed by the caller once handled: counted now for the sweep's trim
  if (partial_.capacity() > k_kept_buffer_bytes) freed(partial_.capacity());
  std::string line = std::move(partial_);
  partial_ = std::string();
  return line;
}

void LineConnection::input_ended() {
  // the client finished sending: answer what it asked, then close
  if (!partial_.empty() && !discarding_) {
    const std::string last = take_line();
    deliver(last);
    if (closed()) return;
    server().on_messages_done(*this, /*read_finished=*/true);
  }
  lines_.on_input_ended(*this);
  end_of_input();
}

void LineConnection::consume(std::string_view data) {
  // a large read is offered to the server in two halves (on_messages_done)
  std::size_t half_left = data.size() >= ReadSplit::k_min_bytes ? data.size() / 2 : 0;
  while (!data.empty() && !closed()) {
    if (half_left && data.size() <= half_left) {
      half_left = 0;
      server().on_messages_done(*this, /*read_finished=*/false);
      // its replies may have closed the connection (the client does not read them): the
      // rest of the read is dropped, not taken as requests of a closed connection
      if (closed()) return;
    }
    const std::size_t nl = data.find('\n');
    if (discarding_) {
      // the tail of an oversized line: skip to its end
      if (nl == std::string_view::npos) return;
      discarding_ = false;
      data.remove_prefix(nl + 1);
      continue;
    }
    if (nl == std::string_view::npos) {
      // an unfinished line: keep it, unless it is already too long
      if (partial_.size() + data.size() > limits_.max_message_bytes) {
        oversized(data, partial_.size() + data.size());
        discarding_ = true;
        message_begun();  // its rest must come within line_timeout_s too
      } else {
        grow_line(data);
      }
      return;
    }
    const std::string_view piece = data.substr(0, nl);
    data.remove_prefix(nl + 1);
    if (partial_.size() + piece.size() > limits_.max_message_bytes) {
      oversized(piece, partial_.size() + piece.size());
    } else if (partial_.empty()) {
      deliver(piece);  // fast path: the whole line is in this read
    } else {
      const std::string line = take_line(piece);
      deliver(line);
    }
  }
}

void LineConnection::deliver(std::string_view line) {
  if (!is_http_request_line(line)) {
    // a blank line is no request: a client sending only those is idle (it does not keep
    // its place at max_connections, issue #35 item 9)
    if (!is_blank(line)) active();
    lines_.on_line(*this, line);
    return;
  }
  // a web page posting to this port (fetch with mode "no-cors"): its headers and its body
  // would be read as lines of this protocol, so nothing more is read
  if (line.back() == '\r') line.remove_suffix(1);
  log::warning(who_, ": ", label_, ": closed on an HTTP request line (", log::quoted_prefix(line),
               "): this port does not speak HTTP; nothing that followed it was run");
  close("an HTTP request line");
}

void LineConnection::oversized(std::string_view start, std::size_t bytes) {
  // the host sees the line's first KiB; what was kept of it goes back to the allocator
  std::string prefix = take_line();
  if (prefix.size() < k_oversized_prefix)
    prefix.append(start.substr(0, std::min(start.size(), k_oversized_prefix - prefix.size())));
  else
    prefix.resize(k_oversized_prefix);
  lines_.on_oversized_line(*this, prefix, bytes);
}

void LineConnection::on_close() {
  freed(partial_.capacity());
  std::string().swap(partial_);
}

}  // namespace simgate::kit
