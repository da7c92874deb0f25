// simgate/kit/http_connection.h — HTTP/1.1 on the kit's connection: requests answered in turn
// on a kept-alive connection, each by one whole response or by a stream of server-sent
// events (the mcp transport's streamable HTTP).
//
// An HttpConnection is the kit's connection (connection.h: reads, coalesced writes, the
// budgets of unsent bytes and of all connections' memory, the idle and unfinished-message
// timers, auth, close) with what is HTTP's own:
//   - Requests: Beast's parser reads each request (header within k_max_header_bytes, body
//     within max_message_bytes, Content-Length or chunked) from the bytes the connection
//     reads; a complete one goes to the host (HttpHost::on_request). One request is answered
//     at a time: while it is, reading pauses and bytes of a next one that came with it wait
//     (pipelining works, in order). `Expect: 100-continue` is answered 100 before the body.
//   - Bad requests: a header too large is answered 431, a body too large 413, anything the
//     parser refuses 400, each naming the limit or the error, and the connection closes; the
//     server keeps serving everyone else.
//   - Answers: respond() writes a whole response (Content-Length); begin_events(),
//     queue_event() and end_events() a stream of server-sent events (text/event-stream,
//     chunked; the response of an HTTP/1.0 request ends with the connection instead). A
//     request answered, the next is read; `Connection: close` (or HTTP/1.0 without
//     keep-alive) closes the connection once the answer is written.
//   - End of input: the connection closes once the request being answered is answered.
//   - A request begun must end within line_timeout_s (the connection's message_ticks), as a
//     line must on the line transports.
//
// A transport derives its manager from HttpServer (implementing HttpHost::on_request and
// ConnectionServer's on_messages_done and on_closed: its protocol).
//
// Threads: the transport's I/O thread only.
#ifndef SIMGATE_KIT_HTTP_CONNECTION_H_
#define SIMGATE_KIT_HTTP_CONNECTION_H_

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <boost/beast/http/parser.hpp>

#include "simgate/kit/connection.h"
#include "simgate/kit/http.h"

namespace simgate::kit {

class HttpConnection;

// What an HTTP connection hands to its transport: the requests.
class HttpHost {
 public:
  virtual ~HttpHost() = default;
  // One complete request: the host answers it, now or later (respond(), or begin_events()
  // ... end_events()); the connection reads its next request once it is answered.
  virtual void on_request(HttpConnection& connection, HttpRequest&& request) = 0;
};

// The server of an HTTP transport: the kit's connection server with the requests' host.
class HttpServer : public ConnectionServer, public HttpHost {
 public:
  using ConnectionServer::ConnectionServer;
};

class HttpConnection : public Connection {
 public:
  // `server_name` is what responses say in their Server header ("simgate mcp transport").
  HttpConnection(boost::asio::ip::tcp::socket socket, HttpServer& server, ConnectionLimits limits,
                 std::string_view who, std::uint64_t number, std::string server_name);

  void start() override { start_reading(); }

  // ---- answering the request being served (at most one at a time)
  // A whole response: `status`, `content_type`, `headers` (extra header lines, each ending
  // in "\r\n"), `body`. Written at the end of the burst; the kit's budgets apply.
  void respond(unsigned status, std::string_view content_type, std::string_view body,
               std::string_view headers = {});
  // Begins a 200 response of server-sent events, with extra `headers`.
  void begin_events(std::string_view headers = {});
  // One event whose data is `data` (one line: no '\n' or '\r'), of event id `id` ("": none).
  void queue_event(std::string_view data, std::string_view id = {});
  // The same, dropped (false) when the client lets bytes pile up unread
  // (Connection::k_droppable_unsent_bytes): a progress report.
  bool queue_droppable_event(std::string_view data);
  // Ends the stream of events: the request is answered.
  void end_events();
  // The connection closes once the request being answered is (a refusal: one guess per
  // connection).
  void close_after_answer() { close_after_ = true; }
  // Whether a request is being answered (read, not yet answered).
  bool answering() const { return answering_; }
  // Whether its answer is a stream of events, begun and not ended.
  bool streaming() const { return streaming_; }

  // The largest request header accepted.
  static constexpr std::uint32_t k_max_header_bytes = 16 * 1024;

 protected:
  // ---- Connection: the framing
  void consume(std::string_view data) override;
  void input_ended() override { end_of_input(); }
  bool message_unfinished() const override { return !answering_ && parser_.has_value(); }
  void on_written() override;

 private:
  using Parser = boost::beast::http::request_parser<boost::beast::http::string_body>;

  // Parses what is waiting into requests, each handed to the host, until one is being
  // answered or the bytes run out.
  void parse_waiting();
  // A request the parser refused: answered with `status` naming `why`, then closed.
  void refuse(unsigned status, std::string_view why);
  // The status line and the headers every response has.
  void append_head(std::string& out, unsigned status, std::string_view content_type) const;
  // The request is answered: the next one is read (or the connection closes).
  void answered();

  HttpHost& host_;
  std::string server_name_;       // the Server header
  std::optional<Parser> parser_;  // the request being read (none between requests)
  std::string waiting_;           // bytes read and not yet parsed
  bool parsing_ = false;          // parse_waiting() is on the stack
  bool answering_ = false;        // a request was handed to the host and is not answered
  bool streaming_ = false;        // its answer is a stream of events
  bool chunked_ = true;           // the stream is chunked (HTTP/1.1)
  bool close_after_ = false;      // the connection closes once the answer is written
  bool continued_ = false;        // `100 Continue` was sent for the request being read
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_HTTP_CONNECTION_H_
