#include "jsonrpc_request_manager.h"

#include "simgate/jsonrpc/protocol.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"

namespace simgate::jsonrpc {

namespace asio = boost::asio;
using asio::ip::tcp;

namespace {
// the most one read takes: large batches arrive in few reads
constexpr std::size_t k_read_bytes = 64 * 1024;
}  // namespace

JsonRpcRequestManager::JsonRpcRequestManager(const json& options)
    : JsonRpcRequestManager(Options::parse(options)) {}

JsonRpcRequestManager::JsonRpcRequestManager(Options o)
    : JsonRpcEngine("JSON-RPC service manager", "jsonrpc", std::move(o)),
      LineServer(name(), options_.tcp),
      // bound now, so that a port in use fails the creation of the transport
      listener_(io_, name(), options_.tcp.host, options_.tcp.port),
      io_thread_(io_, name(), options_.tcp.io_spin) {}

JsonRpcRequestManager::~JsonRpcRequestManager() { stop(); }

std::vector<std::string> JsonRpcRequestManager::endpoints() const { return {listener_.endpoint()}; }

void JsonRpcRequestManager::start() {
  kit::TcpListener::Handlers handlers{
      [this](tcp::socket socket) { accept(std::move(socket)); },
      [this](const tcp::endpoint& peer) { return refusal_reason(peer); },
      [](const std::string& why) {
        return dump(error_response(nullptr, code::overloaded, "Overloaded: " + why)) + "\n";
      }};
  if (io_thread_.start(
          [this, handlers = std::move(handlers)]() mutable {
            deliver_here();
            listener_.start(std::move(handlers));
          },
          direct_reads()))
    log::info("jsonrpc: listening on ", endpoints().front());
}

void JsonRpcRequestManager::stop() {
  if (!io_thread_.stop([this] { shutdown_io(); })) return;
  finish_stop();
}

void JsonRpcRequestManager::shutdown_io() {
  stop_io();
  listener_.close();
  close_all();
}

void JsonRpcRequestManager::accept(tcp::socket socket) {
  kit::ConnectionLimits limits = kit::ConnectionLimits::from(options_.tcp);
  // a call over max_in_flight is answered -32006 (dispatch), never left unread; a client
  // that lets its replies pile up stops being read at half the unsent budget
  limits.pause_at_unsent_bytes = options_.tcp.max_unsent_bytes / 2;
  limits.read_bytes = k_read_bytes;
  kit::LineServer& server = *this;
  const std::uint64_t number = next_session_++;
  client_arrived(number);
  add(std::make_shared<LineSession>(std::move(socket), server, limits, name(), number));
}

// ---- kit::LineServer: the framing (I/O thread)

void JsonRpcRequestManager::on_line(kit::LineConnection& connection, std::string_view line) {
  handle_message(static_cast<LineSession&>(connection), line);
}

void JsonRpcRequestManager::on_oversized_line(kit::LineConnection& connection,
                                              std::string_view /*prefix*/, std::size_t bytes) {
  const auto max = options_.tcp.max_message_bytes;
  static_cast<LineSession&>(connection)
      .queue_message(dump(error_response(
          nullptr, code::invalid_request,
          "Invalid Request: message exceeds max_message_bytes (" + std::to_string(max) + ")",
          json{{"reason", "message too large"},
               {"bytes_so_far", bytes},
               {"max_message_bytes", max}})));
}

void JsonRpcRequestManager::on_messages_done(kit::Connection& connection, bool read_finished) {
  // a large read from a client pipelining alone: its first half runs and is answered
  // before the rest is parsed (simgate/kit/read_split.h)
  if (read_finished) {
    flush_submissions();  // answered at write_replies(), with the next read's if it is waiting
  } else if (alone(connection)) {
    flush_submissions();
    flush_touched();
  }
}

void JsonRpcRequestManager::on_input_ended(kit::LineConnection& connection) {
  input_ended(static_cast<LineSession&>(connection));
}

void JsonRpcRequestManager::on_closed(kit::Connection& connection) {
  session_closed(static_cast<LineSession&>(connection));
}

}  // namespace simgate::jsonrpc

SIMGATE_TRANSPORT_PLUGIN(jsonrpc, simgate::jsonrpc::JsonRpcRequestManager, "0.1.0", "host", "port",
                         "max_message_bytes", "max_depth", "max_in_flight", "max_unsent_bytes",
                         "max_connections", "io_spin_us", "on_disconnect", "global_policy",
                         "idle_timeout_s", "idle_evict_s", "line_timeout_s", "max_buffered_bytes",
                         "max_connections_per_peer", "auth", "progress_interval_ms", "stream_queue")
