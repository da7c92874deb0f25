// simgate/kit/line_connection.h — the line framing on the kit's connection: one message
// per '\n'-terminated line in both directions (the socket and jsonrpc transports).
//
// A LineConnection is a kit::Connection (connection.h: reads, writes, budgets, timers,
// auth, close) that frames messages as lines:
//   - Bytes accumulate until '\n', so a message split over TCP segments works and several
//     in one segment are all seen. A line longer than max_message_bytes is handed to the
//     host as its first KiB (LineHost::on_oversized_line: the protocol answers it) and
//     skipped up to its '\n'; the connection keeps working. At end of input a last line
//     without its '\n' still counts (telnet, `printf` without \n).
//   - A large read of a client sending alone (read_split.h): the server is offered the first
//     half (on_messages_done(false)) to run and answer it before the rest is parsed.
//   - End of input: the host is told (on_input_ended: it may cancel what the client left
//     running); the connection stays open until every reply it owes is written, then closes
//     (so `echo req | nc` gets its answer).
//   - Cross-site requests: a line that is an HTTP request line ("POST / HTTP/1.1": what a
//     browser sends first when a web page posts to the port) closes the connection before
//     the host sees it, so neither the headers nor the body that follow are ever taken as
//     requests (is_http_request_line).
//   - A line begun must end within line_timeout_s (the connection's message_ticks); its
//     unfinished part counts against max_buffered_bytes (the connection that would pass it
//     is closed).
//
// A transport derives its session from LineConnection (adding its per-connection state:
// pending ids) and its manager from LineServer (implementing the LineHost calls and
// ConnectionServer's on_messages_done and on_closed: its protocol);
// docs/writing-a-transport.md shows one.
//
// Threads: every member function runs on the transport's single I/O thread.
#ifndef SIMGATE_KIT_LINE_CONNECTION_H_
#define SIMGATE_KIT_LINE_CONNECTION_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "simgate/kit/connection.h"
#include "simgate/kit/http_line.h"

namespace simgate::kit {

class LineConnection;

// What a line connection hands to its transport: the lines.
class LineHost {
 public:
  virtual ~LineHost() = default;
  // One complete line, without its '\n' (a '\r' before it is kept: the protocol decides).
  virtual void on_line(LineConnection& connection, std::string_view line) = 0;
  // A line exceeded max_message_bytes: `prefix` is its first KiB (to find the client's id),
  // `bytes` how much of it had arrived. Its rest is skipped.
  virtual void on_oversized_line(LineConnection& connection, std::string_view prefix,
                                 std::size_t bytes) = 0;
  // The client shut down its sending side (or closed): it will send nothing more.
  virtual void on_input_ended(LineConnection& connection) = 0;
};

// The server of a line transport: the kit's connection server with the lines' host.
class LineServer : public ConnectionServer, public LineHost {
 public:
  using ConnectionServer::ConnectionServer;
};

class LineConnection : public Connection {
 public:
  // `who` names the transport in logs ("Socket service manager"); `number` the connection
  // ("client #3 (127.0.0.1:51234)").
  LineConnection(boost::asio::ip::tcp::socket socket, LineServer& server, ConnectionLimits limits,
                 std::string_view who, std::uint64_t number)
      : Connection(std::move(socket), server, limits, who, number), lines_(server) {}

  // Lines need no handshake: reads at once.
  void start() override { start_reading(); }

  // Queues reply bytes (whole lines, '\n' included) for the next flush_writes().
  void queue(std::string_view bytes) {
    queue_with([bytes](std::string& out) { out.append(bytes); });
  }
  // queue() and flush_writes().
  void send(std::string_view bytes) {
    queue(bytes);
    flush_writes();
  }

 protected:
  void consume(std::string_view data) override;
  void input_ended() override;
  bool message_unfinished() const override { return !partial_.empty() || discarding_; }
  void on_close() override;

 private:
  void deliver(std::string_view line);  // to the host, unless it is an HTTP request line
  void oversized(std::string_view start, std::size_t bytes);
  // The partial line grows only within max_buffered_bytes (false: the connection was
  // closed instead).
  bool grow_line(std::string_view data);
  // The unfinished line with `end` appended, taken out of the connection.
  std::string take_line(std::string_view end = {});

  LineHost& lines_;          // the transport's protocol
  std::string partial_;      // the start of an unfinished line
  bool discarding_ = false;  // skipping the rest of an oversized line
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_LINE_CONNECTION_H_
