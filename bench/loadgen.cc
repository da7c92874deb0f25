// loadgen.cc — the one TCP client every line-protocol server is measured with.
//
// The echo limit, simgate's socket and JSON-RPC transports, MORSE's Python request manager,
// the npm JSON-RPC peer and the gateway are all driven by this program, so a ratio between
// two of them compares servers, not clients. It speaks raw lines over 127.0.0.1 TCP
// (TCP_NODELAY) and never parses more than it must to validate a reply.
//
// Modes (--mode):
//   latency      one connection, one request outstanding: --count round trips after
//                --warmup, reported as percentiles (µs).
//   throughput   --connections C connections, each keeping --window W requests in flight
//                (every reply read is answered by a new request, all written at once) for
//                --duration seconds after --warmup-seconds; reports replies per second.
//   rate         open loop: --rate R requests per second over one connection for
//                --duration seconds (the load while the gateway runs in real time);
//                reports the achieved rate and latency percentiles (replies arrive in order).
//   hold         opens --count idle connections, prints {"connected": N}, keeps them until
//                its standard input closes or --duration passes (memory per connection).
//
// Request lines (--proto): `ws-jsonrpc` is `jsonrpc` over a WebSocket (one request per
// text message, no '\n'; Boost.Beast's client; --mode latency only), for the websocket
// transport measured against the TCP one in the same run. `foxglove` is a Foxglove
// WebSocket client (subprotocol foxglove.websocket.v1; --mode latency only): it finds the
// service --method names ("test_component.add" is "/test_component/add") in the server's
// advertiseServices, then sends binary service call requests with --params as the JSON
// request and waits for each binary response (Time messages and statuses skipped). `mcp` is
// an MCP client over streamable HTTP (raw HTTP/1.1 on this program's connection, kept alive;
// --mode latency only): it initializes a session at /mcp, then POSTs tools/call of the tool
// --method names ("test_component.add" is "test_component_add") with --params (an object) as
// its arguments, and expects each answer as JSON without isError. `socket` sends "<id> <--request>"
// (default "test_component add [1, 2]") and expects "<id> SUCCESS|OK ..."; `jsonrpc` sends
// {"jsonrpc":"2.0","id":<id>,"method":<--method>,"params":<--params>} and expects a
// "result". --echo expects the request back unchanged (the echo server). A reply that does
// not match counts as an error; the harness refuses results with errors.
//
// Every loop is bounded by a count and a deadline. Results: one JSON object on stdout.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstring>
#include <deque>
#include <optional>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/websocket.hpp>

#include "bench_util.h"

namespace {

using simgate::bench::Clock;
using simgate::bench::json;

// How requests are written and replies recognised.
struct Protocol {
  std::string proto = "socket";  // "socket", "jsonrpc", "ws-jsonrpc", "foxglove" or "mcp"
  std::string request = "test_component add [1, 2]";  // socket: everything after the id
  std::string method = "test_component.add";          // jsonrpc method
  std::string params = "[1,2]";                       // jsonrpc params (JSON text)
  bool echo = false;                                  // replies are the requests, unchanged

  // Appends request `id` (with its '\n') to `out`.
  void append_request(std::uint64_t id, std::string& out) const {
    if (proto == "jsonrpc" || proto == "ws-jsonrpc") {
      out += R"({"jsonrpc":"2.0","id":)";
      out += std::to_string(id);
      out += R"(,"method":")";
      out += method;
      out += R"(","params":)";
      out += params;
      out += proto == "jsonrpc" ? "}\n" : "}";
    } else {
      out += std::to_string(id);
      out += ' ';
      out += request;
      out += '\n';
    }
  }

  // True when `line` (without '\n') is a successful reply.
  bool reply_ok(std::string_view line) const {
    if (echo) return !line.empty();
    if (proto != "socket") return line.find("\"result\"") != std::string_view::npos;
    auto space = line.find(' ');
    if (space == std::string_view::npos) return false;
    auto status = line.substr(space + 1);
    return status.rfind("SUCCESS", 0) == 0 || status.rfind("OK", 0) == 0;
  }
};

// One TCP connection with a line reader. Non-blocking; waits use poll with deadlines.
class Connection {
 public:
  Connection(const std::string& host, int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd_ < 0) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(port));
    if (inet_pton(AF_INET, host.c_str(), &addr.sin_addr) != 1)
      throw std::runtime_error("host '" + host + "': expected an IPv4 address");
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
      throw std::runtime_error("connect " + host + ":" + std::to_string(port) + ": " +
                               std::strerror(errno));
    int one = 1;
    ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    ::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) | O_NONBLOCK);
  }
  ~Connection() {
    if (fd_ >= 0) ::close(fd_);
  }
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  int fd() const { return fd_; }

  // Queues bytes and writes what the socket takes now.
  void send(std::string_view bytes) {
    out_.append(bytes);
    flush();
  }
  // Writes queued bytes until the socket would block.
  void flush() {
    while (sent_ < out_.size()) {
      ssize_t n = ::send(fd_, out_.data() + sent_, out_.size() - sent_, MSG_NOSIGNAL);
      if (n > 0) {
        sent_ += static_cast<std::size_t>(n);
      } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        return;
      } else if (n < 0 && errno == EINTR) {
        continue;
      } else {
        throw std::runtime_error(std::string("send: ") + std::strerror(errno));
      }
    }
    out_.clear();
    sent_ = 0;
  }
  bool wants_write() const { return sent_ < out_.size(); }

  // Reads what is available; returns false if nothing was (would block).
  bool read_some() {
    char chunk[65536];
    ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n > 0) {
      in_.append(chunk, static_cast<std::size_t>(n));
      return true;
    }
    if (n == 0) throw std::runtime_error("the server closed the connection");
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return false;
    throw std::runtime_error(std::string("recv: ") + std::strerror(errno));
  }

  // Calls fn(line) for every complete line received; returns how many.
  template <class F>
  std::size_t take_lines(F&& fn) {
    std::size_t count = 0, start = 0;
    for (;;) {
      auto nl = in_.find('\n', start);
      if (nl == std::string::npos) break;
      std::string_view line(in_.data() + start, nl - start);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      fn(line);
      ++count;
      start = nl + 1;
    }
    in_.erase(0, start);
    return count;
  }

  // Waits for the next line until `deadline`; throws on timeout.
  std::string wait_line(Clock::time_point deadline) {
    for (;;) {
      auto nl = in_.find('\n');
      if (nl != std::string::npos) {
        std::string line = in_.substr(0, nl);
        in_.erase(0, nl + 1);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        return line;
      }
      if (read_some()) continue;
      wait(POLLIN, deadline);
    }
  }

  // Waits for the next `n` bytes until `deadline`; throws on timeout.
  std::string wait_bytes(std::size_t n, Clock::time_point deadline) {
    while (in_.size() < n) {
      if (read_some()) continue;
      wait(POLLIN, deadline);
    }
    std::string bytes = in_.substr(0, n);
    in_.erase(0, n);
    return bytes;
  }

  // Blocks until `events` or `deadline` (throws on timeout).
  void wait(short events, Clock::time_point deadline) {
    auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) throw std::runtime_error("timed out waiting for the server");
    pollfd p{fd_, events, 0};
    ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 1000)));
  }

 private:
  int fd_ = -1;           // the socket
  std::string in_;        // received, not yet returned as lines
  std::string out_;       // queued for sending
  std::size_t sent_ = 0;  // bytes of out_ already sent
};

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// What a latency run reports: the round trips' percentiles (µs), the wrong replies, the
// first reply (what the harness shows when there are errors).
json latency_result(std::vector<std::int64_t> samples, std::size_t errors,
                    const std::string& first_reply) {
  json out = simgate::bench::summarize_us(std::move(samples));
  out["mode"] = "latency";
  out["errors"] = errors;
  out["first_reply"] = first_reply;
  return out;
}

// One request outstanding: round-trip percentiles.
json run_latency(const std::string& host, int port, const Protocol& p, std::size_t count,
                 std::size_t warmup, double timeout_s) {
  Connection c(host, port);
  std::vector<std::int64_t> samples;
  samples.reserve(count);
  std::size_t errors = 0;
  std::string first_reply, request;
  auto deadline = Clock::now() + seconds(timeout_s);
  for (std::size_t i = 0; i < warmup + count; ++i) {
    request.clear();
    p.append_request(i + 1, request);
    auto t0 = Clock::now();
    c.send(request);
    while (c.wants_write()) {
      c.wait(POLLOUT, deadline);
      c.flush();
    }
    std::string line = c.wait_line(deadline);
    auto t1 = Clock::now();
    if (i == 0) first_reply = line;
    if (!p.reply_ok(line) || (p.echo && line + "\n" != request)) ++errors;
    if (i >= warmup) samples.push_back(simgate::bench::ns_between(t0, t1));
  }
  return latency_result(std::move(samples), errors, first_reply);
}

using WsStream = boost::beast::websocket::stream<boost::asio::ip::tcp::socket>;

// A blocking Beast client's connection (TCP_NODELAY; every read bounded by `timeout_s`,
// SO_RCVTIMEO), upgraded offering `subprotocol` (none when empty).
void connect_websocket(WsStream& stream, const std::string& host, int port, double timeout_s,
                       const std::string& subprotocol = "") {
  namespace ws = boost::beast::websocket;
  stream.next_layer().connect(
      {boost::asio::ip::make_address(host), static_cast<std::uint16_t>(port)});
  stream.next_layer().set_option(boost::asio::ip::tcp::no_delay(true));
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout_s);
  ::setsockopt(stream.next_layer().native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  if (!subprotocol.empty())
    stream.set_option(ws::stream_base::decorator([subprotocol](ws::request_type& request) {
      request.set(boost::beast::http::field::sec_websocket_protocol, subprotocol);
    }));
  stream.handshake(host + ":" + std::to_string(port), "/");
}

// run_latency over a WebSocket (--proto ws-jsonrpc): a blocking Beast client, one text
// message per request; the run's deadline bounds every read (SO_RCVTIMEO).
json run_ws_latency(const std::string& host, int port, const Protocol& p, std::size_t count,
                    std::size_t warmup, double timeout_s) {
  namespace ws = boost::beast::websocket;
  boost::asio::io_context io;
  WsStream stream(io);
  connect_websocket(stream, host, port, timeout_s);
  stream.text(true);
  std::vector<std::int64_t> samples;
  samples.reserve(count);
  std::size_t errors = 0;
  std::string first_reply, request;
  boost::beast::flat_buffer buffer;
  const auto deadline = Clock::now() + seconds(timeout_s);
  for (std::size_t i = 0; i < warmup + count; ++i) {
    if (Clock::now() > deadline) throw std::runtime_error("timed out waiting for the server");
    request.clear();
    p.append_request(i + 1, request);
    buffer.clear();
    auto t0 = Clock::now();
    stream.write(boost::asio::buffer(request));
    stream.read(buffer);
    auto t1 = Clock::now();
    std::string_view reply(static_cast<const char*>(buffer.cdata().data()), buffer.size());
    if (i == 0) first_reply = reply;
    if (!p.reply_ok(reply)) ++errors;
    if (i >= warmup) samples.push_back(simgate::bench::ns_between(t0, t1));
  }
  boost::system::error_code ignored;
  stream.close(ws::close_code::normal, ignored);
  return latency_result(std::move(samples), errors, first_reply);
}

// run_latency as a Foxglove client (--proto foxglove): a blocking Beast client; the service
// is found in advertiseServices, each call is a binary service call request answered by a
// binary response (0x03) carrying the result; what else comes meanwhile (Time messages,
// statuses) is read past. The run's deadline bounds every read (SO_RCVTIMEO).
json run_foxglove_latency(const std::string& host, int port, const Protocol& p, std::size_t count,
                          std::size_t warmup, double timeout_s) {
  namespace ws = boost::beast::websocket;
  boost::asio::io_context io;
  WsStream stream(io);
  connect_websocket(stream, host, port, timeout_s, "foxglove.websocket.v1");
  const auto deadline = Clock::now() + seconds(timeout_s);
  boost::beast::flat_buffer buffer;
  // the service's id, from advertiseServices
  std::string name = "/" + p.method;
  for (char& c : name)
    if (c == '.') c = '/';
  std::optional<std::uint32_t> service;
  while (!service) {
    if (Clock::now() > deadline) throw std::runtime_error("no service " + name + " advertised");
    buffer.clear();
    stream.read(buffer);
    if (!stream.got_text()) continue;
    const json m = json::parse(boost::beast::buffers_to_string(buffer.cdata()), nullptr, false);
    if (!m.is_object() || m.value("op", "") != "advertiseServices") continue;
    for (const auto& s : m["services"])
      if (s.value("name", "") == name) service = s["id"].get<std::uint32_t>();
  }
  const auto put_u32 = [](std::string& out, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
  };
  stream.binary(true);
  std::vector<std::int64_t> samples;
  samples.reserve(count);
  std::size_t errors = 0;
  std::string first_reply, request;
  for (std::size_t i = 0; i < warmup + count; ++i) {
    if (Clock::now() > deadline) throw std::runtime_error("timed out waiting for the server");
    const auto call = static_cast<std::uint32_t>(i + 1);
    request.assign(1, '\x02');
    put_u32(request, *service);
    put_u32(request, call);
    put_u32(request, 4);
    request += "json";
    request += p.params;
    auto t0 = Clock::now();
    stream.write(boost::asio::buffer(request));
    std::string reply;
    for (;;) {  // the response to this call; Time messages and statuses are read past
      buffer.clear();
      stream.read(buffer);
      reply = boost::beast::buffers_to_string(buffer.cdata());
      if (!stream.got_text() && reply.size() >= 9 && reply[0] == '\x03') break;
      if (stream.got_text() && reply.find("serviceCallFailure") != std::string::npos) break;
    }
    auto t1 = Clock::now();
    if (i == 0) first_reply = reply;
    // 0x03, service, call, encoding length 4, "json", the result
    if (reply.size() < 17 || reply[0] != '\x03' || reply.compare(13, 4, "json") != 0) ++errors;
    if (i >= warmup) samples.push_back(simgate::bench::ns_between(t0, t1));
  }
  boost::system::error_code ignored;
  stream.close(ws::close_code::normal, ignored);
  return latency_result(std::move(samples), errors,
                        first_reply.size() > 17 ? first_reply.substr(17) : first_reply);
}

// run_latency as an MCP client (--proto mcp): this program's own connection (the one the
// line protocols are measured with, not an HTTP library), one kept-alive HTTP/1.1 connection;
// initialize, then one tools/call POST per round trip, its JSON answer read by Content-Length.
json run_mcp_latency(const std::string& host, int port, const Protocol& p, std::size_t count,
                     std::size_t warmup, double timeout_s) {
  Connection c(host, port);
  const auto deadline = Clock::now() + seconds(timeout_s);
  std::string session;
  // POSTs `body`; returns the answer's status line and body (the session's id kept)
  const auto post = [&](const std::string& body) {
    std::string request = "POST /mcp HTTP/1.1\r\nHost: " + host +
                          "\r\nContent-Type: application/json\r\n"
                          "Accept: application/json, text/event-stream\r\n";
    if (!session.empty()) request += "Mcp-Session-Id: " + session + "\r\n";
    request += "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n";
    request += body;
    c.send(request);
    const std::string status = c.wait_line(deadline);
    std::size_t length = 0;
    for (std::string line; !(line = c.wait_line(deadline)).empty();) {
      const std::size_t colon = line.find(':');
      if (colon == std::string::npos) continue;
      std::string name = line.substr(0, colon);
      for (char& ch : name) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      const std::string value = line.substr(line.find_first_not_of(' ', colon + 1));
      if (name == "content-length") length = std::stoul(value);
      if (name == "mcp-session-id") session = value;
    }
    return std::make_pair(status, c.wait_bytes(length, deadline));
  };
  const auto initialized = post(
      R"({"jsonrpc":"2.0","id":0,"method":"initialize","params":{"protocolVersion":"2025-11-25",)"
      R"("capabilities":{},"clientInfo":{"name":"simgate_bench_loadgen","version":"1"}}})");
  if (initialized.first.find(" 200 ") == std::string::npos || session.empty())
    throw std::runtime_error("initialize answered " + initialized.first + ": " +
                             initialized.second.substr(0, 200));
  std::string tool = p.method;
  for (char& ch : tool)
    if (ch == '.') ch = '_';
  std::vector<std::int64_t> samples;
  samples.reserve(count);
  std::size_t errors = 0;
  std::string first_reply;
  for (std::size_t i = 0; i < warmup + count; ++i) {
    if (Clock::now() > deadline) throw std::runtime_error("timed out waiting for the server");
    const std::string body = R"({"jsonrpc":"2.0","id":)" + std::to_string(i + 1) +
                             R"(,"method":"tools/call","params":{"name":")" + tool +
                             R"(","arguments":)" + p.params + "}}";
    auto t0 = Clock::now();
    const auto [status, reply] = post(body);
    auto t1 = Clock::now();
    if (i == 0) first_reply = reply;
    if (status.find(" 200 ") == std::string::npos ||
        reply.find(R"("isError":false)") == std::string::npos)
      ++errors;
    if (i >= warmup) samples.push_back(simgate::bench::ns_between(t0, t1));
  }
  return latency_result(std::move(samples), errors, first_reply);
}

// --connections C, --window W in flight each, for --duration seconds after a warm-up (longer,
// up to 10 s more, until at least W x C replies are counted).
json run_throughput(const std::string& host, int port, const Protocol& p, int connections,
                    int window, double warmup_s, double duration_s) {
  std::vector<std::unique_ptr<Connection>> conns;
  std::vector<std::size_t> in_flight(connections, 0);
  for (int i = 0; i < connections; ++i) conns.push_back(std::make_unique<Connection>(host, port));
  std::uint64_t next_id = 1;
  std::string batch;
  auto send_requests = [&](int i, std::size_t n) {
    batch.clear();
    for (std::size_t k = 0; k < n; ++k) p.append_request(next_id++, batch);
    conns[i]->send(batch);
    in_flight[i] += n;
  };
  // fill every window, then keep it full
  for (int i = 0; i < connections; ++i) send_requests(i, static_cast<std::size_t>(window));

  auto start = Clock::now();
  auto measure_from = start + seconds(warmup_s);
  auto measure_to = measure_from + seconds(duration_s);
  const std::uint64_t min_replies =
      static_cast<std::uint64_t>(window) * static_cast<std::uint64_t>(connections);
  constexpr auto k_max_extension = std::chrono::seconds(10);
  auto drain_deadline = measure_to + k_max_extension + std::chrono::seconds(10);
  bool measuring = false, sending = true;
  std::uint64_t replies = 0, errors = 0;
  std::string first_reply;
  Clock::time_point t_first{}, t_last{};
  std::vector<pollfd> fds(connections);
  for (;;) {
    auto now = Clock::now();
    if (!measuring && now >= measure_from) {
      measuring = true;
      t_first = now;
      replies = 0;
    }
    // a figure needs at least one full window per connection: a slow server (MORSE's Python
    // loop on a busy host) gets more time than --duration rather than a rate of 0
    if (sending && now >= measure_to &&
        (replies >= min_replies || now >= measure_to + k_max_extension)) {
      sending = false;
      t_last = now;
    }
    std::size_t outstanding = 0;
    for (auto n : in_flight) outstanding += n;
    if (!sending && outstanding == 0) break;
    if (now >= drain_deadline) throw std::runtime_error("replies still missing 10 s after the run");
    for (int i = 0; i < connections; ++i)
      fds[i] = pollfd{conns[i]->fd(),
                      static_cast<short>(POLLIN | (conns[i]->wants_write() ? POLLOUT : 0)), 0};
    ::poll(fds.data(), fds.size(), 100);
    for (int i = 0; i < connections; ++i) {
      if (fds[i].revents & POLLOUT) conns[i]->flush();
      if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      while (conns[i]->read_some()) {}
      std::size_t got = conns[i]->take_lines([&](std::string_view line) {
        if (first_reply.empty()) first_reply = line;
        if (!p.reply_ok(line)) ++errors;
      });
      in_flight[i] -= got;
      if (sending) {
        replies += got;
        if (got) send_requests(i, got);
      }
    }
  }
  double elapsed = std::chrono::duration<double>(t_last - t_first).count();
  return {
      {"mode", "throughput"}, {"connections", connections},
      {"window", window},     {"replies", replies},
      {"seconds", elapsed},   {"rps", elapsed > 0 ? static_cast<double>(replies) / elapsed : 0.0},
      {"errors", errors},     {"first_reply", first_reply}};
}

// Open loop at --rate requests per second over one connection.
json run_rate(const std::string& host, int port, const Protocol& p, double rate, double duration_s,
              std::size_t max_outstanding) {
  Connection c(host, port);
  std::deque<Clock::time_point> sent_at;  // send times of requests not yet answered (FIFO)
  std::vector<std::int64_t> samples;
  std::uint64_t sent = 0, replies = 0, errors = 0, skipped = 0;
  std::string batch;
  auto start = Clock::now();
  auto stop_sending = start + seconds(duration_s);
  auto drain_deadline = stop_sending + std::chrono::seconds(10);
  for (;;) {
    auto now = Clock::now();
    if (now < stop_sending) {
      // send what is due by now (bounded outstanding: a stalled server cannot grow the queue)
      auto due =
          static_cast<std::uint64_t>(std::chrono::duration<double>(now - start).count() * rate);
      batch.clear();
      while (sent + skipped < due) {
        if (sent_at.size() >= max_outstanding) {
          ++skipped;
          continue;
        }
        p.append_request(sent + 1, batch);
        sent_at.push_back(now);
        ++sent;
      }
      if (!batch.empty()) c.send(batch);
    } else if (sent_at.empty()) {
      break;
    } else if (now >= drain_deadline) {
      throw std::runtime_error("replies still missing 10 s after the run");
    }
    pollfd pfd{c.fd(), static_cast<short>(POLLIN | (c.wants_write() ? POLLOUT : 0)), 0};
    ::poll(&pfd, 1, 1);
    if (pfd.revents & POLLOUT) c.flush();
    if (pfd.revents & (POLLIN | POLLHUP | POLLERR)) {
      while (c.read_some()) {}
      auto t = Clock::now();
      c.take_lines([&](std::string_view line) {
        if (!p.reply_ok(line)) ++errors;
        if (!sent_at.empty()) {
          samples.push_back(simgate::bench::ns_between(sent_at.front(), t));
          sent_at.pop_front();
        }
        ++replies;
      });
    }
  }
  double elapsed = std::chrono::duration<double>(stop_sending - start).count();
  json out = simgate::bench::summarize_us(std::move(samples));
  out["mode"] = "rate";
  out["target_rps"] = rate;
  out["achieved_rps"] = static_cast<double>(replies) / elapsed;
  out["sent"] = sent;
  out["replies"] = replies;
  out["skipped"] = skipped;
  out["errors"] = errors;
  return out;
}

// Opens `count` idle connections and keeps them until stdin closes or the time is up.
json run_hold(const std::string& host, int port, std::size_t count, double duration_s) {
  std::vector<std::unique_ptr<Connection>> conns;
  for (std::size_t i = 0; i < count; ++i) conns.push_back(std::make_unique<Connection>(host, port));
  std::cout << json{{"connected", conns.size()}}.dump() << std::endl;
  auto deadline = Clock::now() + seconds(duration_s);
  char byte;
  while (Clock::now() < deadline) {
    pollfd p{0, POLLIN, 0};
    if (::poll(&p, 1, 100) > 0 && ::read(0, &byte, 1) <= 0) break;  // stdin closed
  }
  // the connections must still be open: a server that dropped them would show here
  std::size_t alive = 0;
  for (auto& c : conns) {
    pollfd p{c->fd(), POLLIN, 0};
    if (::poll(&p, 1, 0) == 0) ++alive;
  }
  return {{"mode", "hold"}, {"connections", count}, {"still_open", alive}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "The TCP line client every line-protocol server is measured with; one JSON object on stdout.",
      "simgate_bench_loadgen"};
  std::string mode = "latency", host = "127.0.0.1";
  int port = 0;
  Protocol p;
  std::size_t count = 2000, max_outstanding = 4096;
  std::optional<std::size_t> warmup;
  double timeout = 60, warmup_s = 0.3, duration = 2, rate = 10000;
  int connections = 1, window = 1;
  app.add_option("--mode", mode, "latency, throughput, rate or hold (see the source's header)")
      ->check(CLI::IsMember({"latency", "throughput", "rate", "hold"}))
      ->capture_default_str();
  app.add_option("--host", host, "the server's address")->capture_default_str();
  app.add_option("--port", port, "the server's port")->required()->check(CLI::Range(1, 65535));
  app.add_option("--proto", p.proto,
                 "socket, jsonrpc, ws-jsonrpc, foxglove or mcp (the last three: latency only)")
      ->check(CLI::IsMember({"socket", "jsonrpc", "ws-jsonrpc", "foxglove", "mcp"}))
      ->capture_default_str();
  app.add_option("--request", p.request, "socket: the request after the id")->capture_default_str();
  app.add_option("--method", p.method, "jsonrpc: the method")->capture_default_str();
  app.add_option("--params", p.params, "jsonrpc: the params (JSON)")->capture_default_str();
  app.add_flag("--echo", p.echo, "expect every request back unchanged (the echo server)");
  app.add_option("--count", count, "latency: round trips measured; hold: connections opened")
      ->capture_default_str();
  app.add_option("--warmup", warmup, "latency: round trips before measuring (default count / 10)");
  app.add_option("--timeout", timeout, "latency: seconds for the whole run")->capture_default_str();
  app.add_option("--connections", connections, "throughput: connections")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--window", window, "throughput: requests in flight per connection")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--warmup-seconds", warmup_s, "throughput: seconds before measuring")
      ->capture_default_str();
  app.add_option("--duration", duration, "throughput, rate, hold: seconds")->capture_default_str();
  app.add_option("--rate", rate, "rate: requests per second")->capture_default_str();
  app.add_option("--max-outstanding", max_outstanding, "rate: requests in flight at most")
      ->capture_default_str();
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  try {
    json out;
    if ((p.proto == "ws-jsonrpc" || p.proto == "foxglove" || p.proto == "mcp") && mode != "latency")
      throw std::runtime_error("--proto " + p.proto + ": --mode latency only");
    if (mode == "latency" && p.proto == "ws-jsonrpc")
      out = run_ws_latency(host, port, p, count, warmup.value_or(count / 10), timeout);
    else if (mode == "latency" && p.proto == "foxglove")
      out = run_foxglove_latency(host, port, p, count, warmup.value_or(count / 10), timeout);
    else if (mode == "latency" && p.proto == "mcp")
      out = run_mcp_latency(host, port, p, count, warmup.value_or(count / 10), timeout);
    else if (mode == "latency")
      out = run_latency(host, port, p, count, warmup.value_or(count / 10), timeout);
    else if (mode == "throughput")
      out = run_throughput(host, port, p, connections, window, warmup_s, duration);
    else if (mode == "rate")
      out = run_rate(host, port, p, rate, duration, max_outstanding);
    else
      out = run_hold(host, port, count, duration);
    std::cout << out.dump() << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_loadgen: " << e.what() << "\n";
    return 1;
  }
}
