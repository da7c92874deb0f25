#include "simgate/kit/http_connection.h"

#include <cstdio>
#include <utility>

#include <boost/beast/http/error.hpp>
#include <boost/beast/http/status.hpp>

#include "simgate/core/log.h"

namespace simgate::kit {

namespace asio = boost::asio;
namespace http = boost::beast::http;

namespace {

// One request at a time: reading pauses while one is being answered.
ConnectionLimits one_at_a_time(ConnectionLimits limits) {
  limits.pause_at_unanswered = 1;
  return limits;
}

}  // namespace

HttpConnection::HttpConnection(asio::ip::tcp::socket socket, HttpServer& server,
                               ConnectionLimits limits, std::string_view who, std::uint64_t number,
                               std::string server_name)
    : Connection(std::move(socket), server, one_at_a_time(limits), who, number),
      host_(server),
      server_name_(std::move(server_name)) {}

void HttpConnection::consume(std::string_view data) {
  waiting_.append(data);
  parse_waiting();
}

void HttpConnection::parse_waiting() {
  if (parsing_) return;  // a request answered at once, inside on_request: the loop goes on
  parsing_ = true;
  while (!answering_ && !closed() && !waiting_.empty()) {
    if (!parser_) {
      parser_.emplace();
      parser_->header_limit(k_max_header_bytes);
      parser_->body_limit(limits_.max_message_bytes);
      parser_->eager(true);
      continued_ = false;
      message_begun();
    }
    boost::system::error_code ec;
    const std::size_t used = parser_->put(asio::buffer(waiting_.data(), waiting_.size()), ec);
    waiting_.erase(0, used);
    if (ec == http::error::need_more) break;  // an unfinished header: wait for more
    if (ec == http::error::header_limit) {
      refuse(431, "the request's header is larger than " + std::to_string(k_max_header_bytes) +
                      " bytes");
      break;
    }
    if (ec == http::error::body_limit) {
      refuse(413, "the request's body is larger than " + std::to_string(limits_.max_message_bytes) +
                      " bytes (the transport's " + limits_.message_bytes_key + ")");
      break;
    }
    if (ec) {
      refuse(400, "a malformed HTTP request (" + ec.message() + ")");
      break;
    }
    if (parser_->is_header_done() && !parser_->is_done() && !continued_) {
      continued_ = true;
      const HttpRequest& request = parser_->get();
      if (auto it = request.find(http::field::expect);
          it != request.end() && boost::beast::iequals(it->value(), "100-continue")) {
        queue_control([](std::string& out) { out += "HTTP/1.1 100 Continue\r\n\r\n"; });
        flush_writes();
      }
    }
    if (!parser_->is_done()) {
      if (used == 0) break;
      continue;
    }
    HttpRequest request = parser_->release();
    parser_.reset();
    close_after_ = !request.keep_alive();
    chunked_ = request.version() >= 11;
    answering_ = true;
    expect_reply();
    host_.on_request(*this, std::move(request));
  }
  // what waits of a request not yet answered counts against max_buffered_bytes
  set_framing_bytes(waiting_.size() + (parser_ ? parser_->get().body().size() : 0));
  parsing_ = false;
}

void HttpConnection::refuse(unsigned status, std::string_view why) {
  log::warning(who_, ": ", label_, ": ", why, "; answered ", status, " and closed");
  parser_.reset();
  waiting_.clear();
  answering_ = true;
  expect_reply();
  close_after_ = true;
  chunked_ = true;
  std::string body = server_name_ + ": " + std::string(why) + "\n";
  respond(status, "text/plain; charset=utf-8", body);
}

void HttpConnection::append_head(std::string& out, unsigned status,
                                 std::string_view content_type) const {
  const auto reason = http::obsolete_reason(static_cast<http::status>(status));
  out += "HTTP/1.1 ";
  out += std::to_string(status);
  out += ' ';
  out.append(reason.data(), reason.size());
  out += "\r\nServer: ";
  out += server_name_;
  out += "\r\nContent-Type: ";
  out += content_type;
  out += "\r\n";
  if (close_after_) out += "Connection: close\r\n";
}

void HttpConnection::respond(unsigned status, std::string_view content_type, std::string_view body,
                             std::string_view headers) {
  if (!answering_ || streaming_) return;
  queue_with([&](std::string& out) {
    append_head(out, status, content_type);
    out += "Content-Length: ";
    out += std::to_string(body.size());
    out += "\r\n";
    out += headers;
    out += "\r\n";
    out += body;
  });
  answered();
}

void HttpConnection::begin_events(std::string_view headers) {
  if (!answering_ || streaming_) return;
  streaming_ = true;
  if (!chunked_) close_after_ = true;  // HTTP/1.0: the stream ends with the connection
  queue_with([&](std::string& out) {
    append_head(out, 200, "text/event-stream");
    out += "Cache-Control: no-cache\r\n";
    if (chunked_) out += "Transfer-Encoding: chunked\r\n";
    out += headers;
    out += "\r\n";
  });
}

namespace {

// One event ("id: ...\ndata: ...\n\n") as a chunk of the response (or bare, unchunked).
void append_event(std::string& out, std::string_view data, std::string_view id, bool chunked) {
  const std::size_t size = (id.empty() ? 0 : 5 + id.size()) + 6 + data.size() + 2;
  if (chunked) {
    char hex[20];
    const int n = std::snprintf(hex, sizeof hex, "%zx\r\n", size);
    out.append(hex, static_cast<std::size_t>(n));
  }
  if (!id.empty()) {
    out += "id: ";
    out += id;
    out += '\n';
  }
  out += "data: ";
  out += data;
  out += "\n\n";
  if (chunked) out += "\r\n";
}

}  // namespace

void HttpConnection::queue_event(std::string_view data, std::string_view id) {
  if (!streaming_) return;
  queue_with([&](std::string& out) { append_event(out, data, id, chunked_); });
}

bool HttpConnection::queue_droppable_event(std::string_view data) {
  if (!streaming_) return false;
  return queue_droppable_with([&](std::string& out) { append_event(out, data, {}, chunked_); });
}

void HttpConnection::end_events() {
  if (!streaming_) return;
  if (chunked_) queue_control([](std::string& out) { out += "0\r\n\r\n"; });
  streaming_ = false;
  answered();
}

void HttpConnection::answered() {
  answering_ = false;
  if (close_after_) {
    flush_writes();
    if (unsent() == 0) close("answered (Connection: close)");
    return;  // else on_written() closes it
  }
  replied();  // reading resumes (and end of input closes once written)
  if (!waiting_.empty()) parse_waiting();
}

void HttpConnection::on_written() {
  if (close_after_ && !answering_) close("answered (Connection: close)");
}

}  // namespace simgate::kit
