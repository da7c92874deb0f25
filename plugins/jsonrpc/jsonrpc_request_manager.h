// plugins/jsonrpc/jsonrpc_request_manager.h — JSON-RPC 2.0 over TCP (newline-delimited).
//
// What: the JSON-RPC engine (simgate/jsonrpc/engine.h: the protocol, shared with the websocket
// transport) framed as one message (request or batch) per `\n`-terminated line, in both
// directions, on the kit's line connections (simgate/kit/line_connection.h). Wire details
// and the error table: docs/transports/jsonrpc.md.
//
// Terms:
//  - session: one accepted TCP connection; call ids are scoped to it.
//  - unsent bytes: replies queued on a session and not yet accepted by the kernel.
//
// Life cycle: the constructor reads the options (ConfigError on bad ones) and binds the
// listening socket (std::runtime_error if the port is taken); start() launches the I/O
// thread; stop() closes every connection, joins the thread and finishes what is still
// pending with Failure::shutdown. stop() is idempotent and the destructor calls it.
//
// Threads: one I/O thread runs the io_context (accept, read, parse, hand over, write),
// polling a little before it sleeps while events come close together and reading a lone
// client's socket itself meanwhile (simgate/kit/idle_spin.h). The calls of one read go to
// the core together (JsonRpcEngine::flush_submissions), run on this thread when the
// simulation lock is free; sessions, pending calls and batches are touched by the I/O
// thread only.
#ifndef SIMGATE_PLUGINS_JSONRPC_JSONRPC_REQUEST_MANAGER_H_
#define SIMGATE_PLUGINS_JSONRPC_JSONRPC_REQUEST_MANAGER_H_

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <boost/asio/ip/tcp.hpp>

#include "session.h"
#include "simgate/jsonrpc/engine.h"
#include "simgate/kit/line_connection.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::jsonrpc {

class JsonRpcRequestManager : public JsonRpcEngine, private kit::LineServer {
 public:
  // Parses the options and binds; throws ConfigError or std::runtime_error.
  explicit JsonRpcRequestManager(const json& options);
  ~JsonRpcRequestManager() override;
  // What the constructor checks of `options`, without binding (the plugin's validate).
  static std::vector<std::string> validate_options(const json& options) {
    return Options::parse(options).tcp.warnings;
  }
  std::size_t client_count() const override { return connection_count(); }

  void start() override;
  void stop() override;
  // {"tcp://127.0.0.1:<port>"} with the bound port.
  std::vector<std::string> endpoints() const override;

  std::uint16_t port() const { return listener_.port(); }

 private:
  explicit JsonRpcRequestManager(Options options);

  // JsonRpcEngine: the end of a burst
  void flush_replies() override { flush_touched(); }

  // kit::LineServer: the framing (I/O thread)
  void on_line(kit::LineConnection& connection, std::string_view line) override;
  void on_oversized_line(kit::LineConnection& connection, std::string_view prefix,
                         std::size_t bytes) override;
  void on_messages_done(kit::Connection& connection, bool read_finished) override;
  void on_input_ended(kit::LineConnection& connection) override;
  void on_closed(kit::Connection& connection) override;

  // A new connection (the listener keeps the count under max_connections).
  void accept(boost::asio::ip::tcp::socket socket);
  void shutdown_io();

  kit::TcpListener listener_;       // the listening socket, bound in the constructor
  kit::IoThread io_thread_;         // runs io_
  std::uint64_t next_session_ = 1;  // numbers connections in logs (I/O thread)
};

}  // namespace simgate::jsonrpc

#endif  // SIMGATE_PLUGINS_JSONRPC_JSONRPC_REQUEST_MANAGER_H_
