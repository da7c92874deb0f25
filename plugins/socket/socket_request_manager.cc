#include "socket_request_manager.h"

#include <boost/asio/post.hpp>

#include "params_parser.h"
#include "simgate/core/config.h"
#include "simgate/core/errors.h"
#include "simgate/core/idle_spin.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"
#include "wire.h"

namespace simgate::socket {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;

namespace {

constexpr std::string_view k_failed = "FAILED";
constexpr std::string_view k_preempted = "PREEMPTED";
// Longest client id echoed in the reply to an oversized line (the line itself is dropped).
constexpr std::size_t k_max_echoed_id = 256;
// How long accepting pauses after accept() failed (out of file descriptors, say).
constexpr std::chrono::milliseconds k_accept_retry{100};

// The address to listen on: a literal, or the first result of resolving a name.
tcp::endpoint resolve_listen_endpoint(const std::string& host, std::uint16_t port) {
  error_code ec;
  auto address = asio::ip::make_address(host, ec);
  if (!ec) return tcp::endpoint(address, port);
  asio::io_context io;
  tcp::resolver resolver(io);
  auto results = resolver.resolve(host, std::to_string(port), ec);
  if (ec || results.empty())
    throw ConfigError("host: cannot resolve '" + host + "': " +
                      (ec ? ec.message() : std::string("no address")));
  return results.begin()->endpoint();
}

// The options the JSON-RPC transport names differently were renamed (one name per knob on
// both TCP transports, issue #16); the old names stay accepted for one release.
struct RenamedOption {
  const char* key;      // the name to use
  const char* old_key;  // the deprecated name
};
constexpr RenamedOption k_max_connections{"max_connections", "max_clients"};
constexpr RenamedOption k_max_message_bytes{"max_message_bytes", "max_line_bytes"};
constexpr RenamedOption k_max_unsent_bytes{"max_unsent_bytes", "max_pending_replies_bytes"};
constexpr RenamedOption k_max_in_flight{"max_in_flight", "max_pending_requests"};

// The key `config` spells the knob with: the old one only if the new one is absent (noted in
// `deprecations`). Both at once is a ConfigError.
const char* spelling(const ConfigObject& config, const RenamedOption& option, std::vector<std::string>& deprecations) {
  if (!config.has(option.old_key)) return option.key;
  if (config.has(option.key))
    throw ConfigError(std::string(option.old_key) + ": the deprecated name of '" + option.key +
                      "', which is set too; keep only '" + option.key + "'");
  deprecations.push_back(std::string("socket: option '") + option.old_key + "' is deprecated, use '" + option.key +
                         "' (the old name goes in the next release)");
  return option.old_key;
}

}  // namespace

SocketOptions SocketOptions::parse(const json& options) {
  // every key read here, unknown keys refused by finish()
  ConfigObject config(options, "");
  SocketOptions o;
  o.host = config.get_string("host", o.host);
  o.port = static_cast<std::uint16_t>(config.get_int("port", o.port, 0, 65535));
  o.success_word = config.get_choice("success_word", o.success_word, {"SUCCESS", "OK"});
  o.limits.message_bytes_key = spelling(config, k_max_message_bytes, o.deprecations);
  o.limits.max_message_bytes =
      static_cast<std::size_t>(config.get_int(o.limits.message_bytes_key, 1 << 20, 64, 1LL << 30));
  o.limits.unsent_bytes_key = spelling(config, k_max_unsent_bytes, o.deprecations);
  o.limits.max_unsent_bytes =
      static_cast<std::size_t>(config.get_int(o.limits.unsent_bytes_key, 8 << 20, 1024, 1LL << 34));
  o.limits.max_in_flight = static_cast<std::size_t>(
      config.get_int(spelling(config, k_max_in_flight, o.deprecations), 1024, 1, 1 << 20));
  o.connections_key = spelling(config, k_max_connections, o.deprecations);
  o.max_connections = static_cast<std::size_t>(config.get_int(o.connections_key, 1024, 1, 1 << 20));
  o.io_spin = std::chrono::microseconds(config.get_int("io_spin_us", o.io_spin.count(), 0, 10000));
  o.global_policy = config.get_choice("global_policy", "reject", {"reject", "preempt"}) == "preempt"
                        ? GlobalPolicy::preempt
                        : GlobalPolicy::reject;
  o.cancel_on_disconnect = config.get_choice("on_disconnect", "cancel", {"cancel", "let_run"}) == "cancel";
  config.finish();
  (void)resolve_listen_endpoint(o.host, o.port);  // a name that does not resolve is a config error
  return o;
}

SocketRequestManager::SocketRequestManager(const json& options)
    : RequestManager("Socket service manager"), work_(asio::make_work_guard(io_)), acceptor_(io_),
      accept_retry_(io_) {
  SocketOptions o = SocketOptions::parse(options);
  host_ = o.host;
  const std::uint16_t requested_port = o.port;
  success_word_ = o.success_word;
  limits_ = o.limits;
  max_connections_ = o.max_connections;
  connections_key_ = o.connections_key;
  io_spin_ = o.io_spin;
  cancel_on_disconnect_ = o.cancel_on_disconnect;
  set_global_policy(o.global_policy);
  // once per transport created (validate_options parses too, and says nothing)
  for (const auto& message : o.deprecations) log::warning(message);

  // bind now, so that a port in use fails the creation of the transport
  tcp::endpoint endpoint = resolve_listen_endpoint(host_, requested_port);
  auto fail = [&](const char* step, const error_code& ec) {
    std::string hint;
    if (ec == asio::error::address_in_use)
      hint = " (another program listens there: `ss -ltnp 'sport = :" + std::to_string(requested_port) +
             "'` names it; stop it, or choose another 'port', 0 for any free one)";
    else if (ec == asio::error::access_denied)
      hint = " (ports below 1024 need privileges)";
    throw std::runtime_error(name() + ": cannot listen on " + host_ + ":" +
                             std::to_string(requested_port) + ": " + step + " failed: " +
                             ec.message() + hint);
  };
  error_code ec;
  acceptor_.open(endpoint.protocol(), ec);
  if (ec) fail("open", ec);
  acceptor_.set_option(tcp::acceptor::reuse_address(true), ec);  // TIME_WAIT only, not a live listener
  acceptor_.bind(endpoint, ec);
  if (ec) fail("bind", ec);
  acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) fail("listen", ec);
  auto bound = acceptor_.local_endpoint(ec);
  if (ec) fail("getsockname", ec);
  port_ = bound.port();
  endpoint_ = bound.address().is_v6()
                  ? "tcp://[" + bound.address().to_string() + "]:" + std::to_string(port_)
                  : "tcp://" + bound.address().to_string() + ":" + std::to_string(port_);
  log::info(name(), " now listening on port ", port_, " (", endpoint_, ")");
}

SocketRequestManager::~SocketRequestManager() {
  stop();
  // the host stopped calling process(): finish what is left (replies go nowhere)
  abandon_pending("the socket transport has stopped");
}

void SocketRequestManager::start() {
  std::lock_guard lock(life_mutex_);
  if (started_ || stopped_) return;
  started_ = true;
  accept_next();
  thread_ = std::thread([this] {
    // outcomes produced on the simulation thread come here: one flush per burst, then one
    // write per connection
    deliver_on_this_thread([this] { asio::post(io_, [this] { flush_replies(); }); });
    for (;;) {
      try {
        run_with_idle_spin(io_, io_spin_, direct_);
        return;
      } catch (const std::exception& e) {
        // handlers do not throw; this is a last line of defence that keeps the server up
        log::error(name(), ": I/O handler threw: ", e.what());
      }
    }
  });
}

void SocketRequestManager::stop() {
  std::lock_guard lock(life_mutex_);
  if (stopped_) return;
  stopped_ = true;
  if (thread_.joinable()) {
    // close everything on the I/O thread, then let run() return
    asio::post(io_, [this] { close_all(); });
    work_.reset();
    thread_.join();
    deliver_on_any_thread();  // the connections are gone: outcomes from now on go nowhere
  } else {
    close_all();
  }
  // handlers that never ran (outcomes posted after the close) are dropped here
  io_.stop();
}

std::vector<std::string> SocketRequestManager::endpoints() const { return {endpoint_}; }

void SocketRequestManager::close_all() {
  stopping_ = true;  // the requests still running end at shutdown (abandon_pending), not as cancels
  error_code ec;
  acceptor_.close(ec);
  accept_retry_.cancel();
  auto sessions = std::move(sessions_);
  sessions_.clear();
  client_count_.store(0, std::memory_order_relaxed);
  for (const auto& s : sessions) s->close("server stopping");
  requests_.clear();
}

void SocketRequestManager::accept_next() {
  acceptor_.async_accept([this](const error_code& ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor_.is_open()) return;
    if (ec) {
      // e.g. out of file descriptors: back off instead of spinning (as the JSON-RPC transport)
      log::warning("socket: accept failed: ", ec.message(), "; accepting again in ", k_accept_retry.count(), " ms");
      accept_retry_.expires_after(k_accept_retry);
      accept_retry_.async_wait([this](const error_code& e) {
        if (!e && acceptor_.is_open()) accept_next();
      });
      return;
    }
    if (sessions_.size() >= max_connections_) {
      refuse(std::move(socket));
    } else {
      refusing_ = false;
      SessionHost& host = *this;
      auto session = std::make_shared<Session>(std::move(socket), host, limits_, next_session_++);
      sessions_.insert(session);
      client_count_.store(sessions_.size(), std::memory_order_relaxed);
      log::debug(name(), ": ", session->label(), " connected");
      session->start();
    }
    accept_next();
  });
}

void SocketRequestManager::refuse(tcp::socket socket) {
  // as the JSON-RPC transport: one warning until a connection is accepted again, then tell
  // the client why in its protocol (one line, best effort, never blocking) and close. The
  // id "-" matches no request: pymorse ignores the line, telnet shows it.
  const std::string why = "too many connections (" + std::string(connections_key_) + " " +
                          std::to_string(max_connections_) + ")";
  error_code ignored;
  const auto peer = socket.remote_endpoint(ignored);
  if (!refusing_)
    log::warning("socket: refused a connection from ", peer.address().to_string(), ":", peer.port(), ": ", why,
                 "; further refusals are logged at debug level until one is accepted");
  else
    log::debug("socket: refused a connection from ", peer.address().to_string(), ":", peer.port(), ": ", why);
  refusing_ = true;
  std::string line;
  const json text = why;
  append_reply(line, "-", k_failed, &text);
  socket.non_blocking(true, ignored);
  socket.write_some(asio::buffer(line), ignored);
  socket.close(ignored);
}

// ---- requests (I/O thread)

void SocketRequestManager::run_calls() {
  if (batch_count_ == 0) return;
  // outcomes produced here, on the I/O thread, are queued on their connections
  // (on_service_completion). The calls stay in batch_ for the next read (those queued for
  // the simulation thread are moved out).
  run_or_submit(std::span(batch_.data(), batch_count_));
  batch_count_ = 0;
  if (batch_.size() > k_kept_calls) batch_.erase(batch_.begin() + k_kept_calls, batch_.end());
  // a client of this read left while it was read: its requests have started, now they end
  if (!cancel_after_batch_.empty()) [[unlikely]] {
    for (RequestId id : cancel_after_batch_) cancel(id);
    cancel_after_batch_.clear();
  }
}

void SocketRequestManager::run_batch() {
  run_calls();
  flush_touched();
}

void SocketRequestManager::on_lines_done(const std::shared_ptr<Session>& session, bool read_finished) {
  // half-way through a large read: its first half runs and is answered now only for a
  // client pipelining alone (read_split.h)
  if (read_finished)
    run_calls();  // answered at write_replies(), with the next read's replies if it is waiting
  else if (read_split_.alone(session.get()))
    run_batch();
}

void SocketRequestManager::write_replies() { flush_touched(); }

void SocketRequestManager::fail_in_order(const std::shared_ptr<Session>& session, std::string_view id,
                                         std::string message) {
  json text = std::move(message);
  // earlier requests of this read may run at once, answering them
  if (session->has_unanswered()) run_batch();
  scratch_.clear();
  append_reply(scratch_, id, k_failed, &text);
  if (!session->has_unanswered()) {
    session->send(scratch_);
    return;
  }
  // earlier requests are still with the core: the answer follows their outcomes, so that a
  // client reading replies in order (telnet, scripts) sees them in order
  session->defer_reply();
  const RequestId reply_id = new_request_id();  // never one of requests_'s ids (RequestSlots::k_mark)
  deferred_replies_.emplace(reply_id, DeferredReply{session, scratch_});
  answer_in_order(reply_id, Outcome{});
}

void SocketRequestManager::on_line(const std::shared_ptr<Session>& session, std::string_view line) {
  RequestLine request = parse_request_line(line);
  switch (request.kind) {
    case RequestLine::Kind::blank:
      return;
    case RequestLine::Kind::malformed:
      fail_in_order(session, request.id, std::move(request.error));
      return;
    case RequestLine::Kind::cancel:
      // no reply of its own: the request ends PREEMPTED; unknown ids are ignored (as MORSE)
      if (const IdTable::Entry* pending = session->find_pending(request.id)) {
        const RequestId id = pending->id;  // read before run_batch() changes the table
        run_batch();                       // the request may be in this read's batch
        cancel(id);
      }
      return;
    case RequestLine::Kind::call:
      break;
  }

  // one pending request per id and connection, or replies could not be told apart
  IdTable::Entry* pending = session->add_pending(request.id);
  if (!pending) {
    fail_in_order(session, request.id,
                  "Request id '" + std::string(request.id) +
                      "' is already pending on this connection: wait for its reply or use another id");
    return;
  }

  // the next call of this read, in an object an earlier read left (its strings and
  // parameter array are refilled: no allocation)
  if (batch_count_ == batch_.size()) batch_.emplace_back();
  auto& [id, call] = batch_[batch_count_];
  if (!parse_params_into(request.params, request.params_column, call.params, params_error_)) {
    session->drop_pending(request.id);
    fail_in_order(session, request.id,
                  params_error_.example.empty()
                      ? "Invalid request syntax: error while parsing the parameters at column " +
                            std::to_string(params_error_.column) + ": " + params_error_.error
                      // `set_speed 0.5 0.2`: bare values where a list belongs
                      : "Invalid request syntax: parameters must be a list, e.g. `" + params_error_.example + "`");
    return;
  }
  if (requests_.size() >= decltype(requests_)::k_max_live) {
    session->drop_pending(request.id);
    fail_in_order(session, request.id, "Too many requests are waiting for their outcome in this server: retry later");
    return;
  }

  // the request's slot: its id says where the reply goes
  id = requests_.insert({session.get(), pending->hash});
  pending->id = id;
  // a pipelining client names the same service line after line
  if (call.component != request.component) call.component.assign(request.component);
  if (call.service != request.service) call.service.assign(request.service);
  // handed to the core with the rest of this read (on_lines_done)
  ++batch_count_;
}

void SocketRequestManager::on_oversized_line(const std::shared_ptr<Session>& session,
                                             std::string_view prefix) {
  // answer with the line's id when it has a usable one, "-" otherwise
  std::size_t begin = 0;
  while (begin < prefix.size() && (prefix[begin] == ' ' || prefix[begin] == '\t')) ++begin;
  std::size_t end = begin;
  while (end < prefix.size() && prefix[end] != ' ' && prefix[end] != '\t' && prefix[end] != '\r') ++end;
  std::string_view id = prefix.substr(begin, end - begin);
  if (id.empty() || id.size() > k_max_echoed_id || end == prefix.size()) id = "-";
  log::warning(name(), ": ", session->label(), ": request line longer than ",
               limits_.max_message_bytes, " bytes ignored");
  fail_in_order(session, id,
                "Request too long: the line exceeds " + std::to_string(limits_.max_message_bytes) + " bytes (" +
                    limits_.message_bytes_key + "); it was ignored");
}

void SocketRequestManager::on_input_ended(const std::shared_ptr<Session>& session) {
  // the client will send nothing more: under "cancel" it has left, and its async requests
  // end (PREEMPTED, written if it still reads); sync ones are answered as usual
  cancel_requests_of(*session);
}

void SocketRequestManager::on_session_closed(const std::shared_ptr<Session>& session) {
  direct_.forget(*session);
  cancel_requests_of(*session);
  // its outcomes have nowhere to go: forget them
  session->pending().for_each([this](const IdTable::Entry& e) { requests_.erase(e.id); });
  sessions_.erase(session);
  client_count_.store(sessions_.size(), std::memory_order_relaxed);
}

void SocketRequestManager::cancel_requests_of(const Session& session) {
  if (!cancel_on_disconnect_ || stopping_) return;
  // every unanswered request: a cancel finds the async ones that run (sync ones are not
  // cancellable, and end as usual). Calls of the read being handled have not reached the
  // core yet: they are cancelled after it (run_calls).
  const bool batch_open = batch_count_ > 0;
  session.pending().for_each([&](const IdTable::Entry& e) {
    if (batch_open)
      cancel_after_batch_.push_back(e.id);
    else
      cancel(e.id);
  });
}

// ---- direct reads (I/O thread)

bool SocketRequestManager::watch(Session& session) {
  // only while the I/O thread polls (it never does with io_spin_us 0), for a client
  // sending alone: others are served by the event loop between direct reads
  if (io_spin_.count() <= 0 || !read_split_.alone(&session)) return false;
  direct_.watch(session.shared_from_this());
  return true;
}

// ---- outcomes

void SocketRequestManager::on_service_completion(RequestId id, Outcome&& outcome) {
  // the I/O thread (deliver_on_this_thread): inside run_or_submit, or flush_replies()
  if (id & decltype(requests_)::k_mark) [[likely]] {
    deliver(id, outcome);
    return;
  }
  // an error reply of fail_in_order(), now that the replies before it are queued
  auto it = deferred_replies_.find(id);
  if (it == deferred_replies_.end()) return;
  DeferredReply reply = std::move(it->second);
  deferred_replies_.erase(it);
  try {
    if (auto s = reply.session.lock(); s && !s->closed()) {
      touch(*s);
      s->queue_deferred_reply(reply.line);
    }
  } catch (const std::exception& e) {
    log::error(name(), ": cannot queue an error reply: ", e.what());
  }
}

void SocketRequestManager::flush_replies() {
  deliver_handed_over();
  flush_touched();
}

void SocketRequestManager::touch(Session& session) {
  if (touched_.empty() || touched_.back().get() != &session) touched_.push_back(session.shared_from_this());
}

void SocketRequestManager::flush_touched() {
  // one write per connection
  for (const auto& s : touched_) s->flush_writes();
  touched_.clear();
}

void SocketRequestManager::deliver(RequestId id, const Outcome& outcome) try {
  const Pending* entry = requests_.find(id);
  if (!entry) return;  // its client is gone
  const Pending pending = *entry;
  requests_.erase(id);  // first: the reply may close the connection, which erases its entries
  Session& session = *pending.session;
  // held in touched_ until its write starts
  touch(session);

  std::string_view status = success_word_;
  if (outcome.status == Status::failed) status = k_failed;
  if (outcome.status == Status::preempted) status = k_preempted;
  // the value is sent even when falsy (0, false, "", []); FAILED without one carries the message
  const json* value = outcome.value ? &*outcome.value : nullptr;
  json message;
  if (!value && outcome.status == Status::failed && !outcome.message.empty()) {
    message = outcome.message;
    value = &message;
  }
  session.answer(pending.client_id_hash, id, status, value);
} catch (const std::exception& e) {
  log::error(name(), ": cannot deliver the outcome of request ", id, ": ", e.what());
}

}  // namespace simgate::socket

SIMGATE_TRANSPORT_PLUGIN(socket, simgate::socket::SocketRequestManager, "0.1.0", "host", "port",
                         "success_word", "max_connections", "max_message_bytes",
                         "max_unsent_bytes", "max_in_flight", "io_spin_us", "global_policy",
                         "on_disconnect",
                         // deprecated names: accepted with a warning until the next release
                         "max_clients", "max_line_bytes", "max_pending_replies_bytes",
                         "max_pending_requests")
