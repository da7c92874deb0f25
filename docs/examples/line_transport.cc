// line_transport.cc — a complete TCP transport on simgate's transport kit: the example of
// docs/writing-a-transport.md, built and tested with the tree (tests/kit/line_transport_test.cc).
//
// Protocol "line": one request per line, `<id> <component> <service> [<JSON params>]`; one
// reply per line, `<id> SUCCESS|FAILED|PREEMPTED <JSON value or message>`. The kit does the
// rest: options, listener, I/O thread, framing and limits, coalesced writes, direct reads.
#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include <boost/asio/post.hpp>

#include "simgate/core/config.h"
#include "simgate/core/plugin.h"
#include "simgate/kit/line_connection.h"
#include "simgate/kit/tcp_server.h"

namespace line {

namespace asio = boost::asio;
namespace kit = simgate::kit;
using simgate::json;

class LineTransport : public simgate::RequestManager, private kit::LineServer {
 public:
  explicit LineTransport(const json& options) : LineTransport(parse(options)) {}
  ~LineTransport() override {
    stop();
    abandon_pending("the line transport has stopped");
  }
  static void validate_options(const json& options) { (void)parse(options); }

  void start() override {
    kit::TcpListener::Handlers handlers{
        [this](asio::ip::tcp::socket socket) { accept(std::move(socket)); },
        [this](const asio::ip::tcp::endpoint& peer) { return refusal_reason(peer); },
        [](const std::string& why) { return "- FAILED \"" + why + "\"\n"; }};
    io_thread_.start(
        [this, handlers = std::move(handlers)]() mutable {
          // outcomes produced on other threads are handed to this one, the I/O thread
          deliver_on_this_thread([this] { asio::post(io_, [this] { flush_replies(); }); });
          listener_.start(std::move(handlers));
        },
        direct_reads());
  }
  void stop() override {
    if (io_thread_.stop([this] { shutdown_io(); })) deliver_on_any_thread();
  }
  std::vector<std::string> endpoints() const override { return {listener_.endpoint()}; }
  std::size_t client_count() const override { return connection_count(); }

 protected:
  // The I/O thread: the reply goes to the connection that asked, if it is still there.
  void on_service_completion(simgate::RequestId id, simgate::Outcome&& outcome) override {
    auto it = pending_.find(id);
    if (it == pending_.end()) return;
    const Pending pending = std::move(it->second);
    pending_.erase(it);
    auto connection = pending.connection.lock();
    if (!connection) return;
    const json value = outcome.value                                ? *outcome.value
                       : outcome.status == simgate::Status::success ? json(nullptr)
                                                                    : json(outcome.message);
    reply(*connection, pending.client_id, to_string(outcome.status), value);
    connection->replied();
  }

 private:
  // Where a request's reply goes.
  struct Pending {
    std::weak_ptr<kit::Connection> connection;
    std::string client_id;
  };

  explicit LineTransport(kit::TcpOptions options)
      : RequestManager("Line service manager"),
        LineServer(name(), options),
        options_(std::move(options)),
        listener_(io_, name(), options_.host,
                  options_.port),  // bound now: a port in use fails here
        io_thread_(io_, name(), options_.io_spin) {
    set_global_policy(options_.global_policy);
  }

  static kit::TcpOptions parse(const json& options) {
    simgate::ConfigObject config(options.is_null() ? json::object() : options, "");
    kit::TcpOptions defaults;
    defaults.port = 4100;
    kit::TcpOptions tcp = kit::TcpOptions::read(config, defaults, "line");
    tcp.finish(config);  // unknown keys are refused
    return tcp;
  }

  void accept(asio::ip::tcp::socket socket) {
    kit::ConnectionLimits limits = kit::ConnectionLimits::from(options_);
    limits.pause_at_unanswered = options_.max_in_flight;  // backpressure: reading waits for answers
    kit::LineServer& server = *this;
    add(std::make_shared<kit::LineConnection>(std::move(socket), server, limits, name(),
                                              ++connections_));
  }

  // ---- kit::LineServer: the protocol (I/O thread)
  void on_line(kit::LineConnection& connection, std::string_view line) override {
    auto word = [&line] {
      const auto begin = std::min(line.find_first_not_of(" \t\r"), line.size());
      const auto end = std::min(line.find_first_of(" \t\r", begin), line.size());
      const std::string_view w = line.substr(begin, end - begin);
      line.remove_prefix(end);
      return std::string(w);
    };
    const std::string id = word();
    simgate::Call call{word(), word(), nullptr};
    if (id.empty()) return;  // a blank line
    if (call.service.empty())
      return reply(connection, id, "FAILED", "expected <id> <component> <service> [<JSON>]");
    if (line.find_first_not_of(" \t\r") != std::string_view::npos) {
      call.params = json::parse(line, nullptr, /*allow_exceptions=*/false);
      if (call.params.is_discarded())
        return reply(connection, id, "FAILED", "the parameters are not JSON");
    }
    const simgate::RequestId request = new_request_id();
    pending_[request] = Pending{connection.shared_from_this(), id};
    connection.expect_reply();
    calls_.emplace_back(request, std::move(call));
  }
  void on_oversized_line(kit::LineConnection& connection, std::string_view, std::size_t) override {
    reply(connection, "-", "FAILED", "line longer than max_message_bytes");
  }
  void on_messages_done(kit::Connection&, bool) override {
    // the calls read so far go to the core together: run here when the simulation lock is
    // free (their replies are queued at once), else on the simulation thread
    if (!calls_.empty()) run_or_submit(std::exchange(calls_, {}));
  }
  void on_input_ended(kit::LineConnection&) override {}  // calls of a client that left run on
  void on_closed(kit::Connection&) override {}  // its pending calls still end (reply() drops them)

  void reply(kit::Connection& connection, std::string_view id, std::string_view status,
             const json& value) {
    connection.queue_with([&](std::string& out) {
      // invalid UTF-8 in a service's string is replaced, never thrown
      out.append(id).append(" ").append(status).append(" ");
      out.append(value.dump(-1, ' ', false, json::error_handler_t::replace)).append("\n");
    });
  }
  // I/O thread, woken by the core: the outcomes of the simulation thread, one write each.
  void flush_replies() {
    deliver_handed_over();
    flush_touched();
  }
  void shutdown_io() {
    listener_.close();
    close_all();
    pending_.clear();
  }

  kit::TcpOptions options_;
  asio::io_context io_;
  kit::TcpListener listener_;
  kit::IoThread io_thread_;
  std::uint64_t connections_ = 0;                                    // numbers connections in logs
  std::unordered_map<simgate::RequestId, Pending> pending_;          // unanswered requests
  std::vector<std::pair<simgate::RequestId, simgate::Call>> calls_;  // read, not yet run
};

}  // namespace line

SIMGATE_TRANSPORT_PLUGIN(line, line::LineTransport, "0.1.0", "host", "port", "max_connections",
                         "max_message_bytes", "max_unsent_bytes", "max_in_flight", "io_spin_us",
                         "on_disconnect", "global_policy", "idle_timeout_s", "idle_evict_s",
                         "line_timeout_s", "max_buffered_bytes")
