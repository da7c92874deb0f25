#include "socket_request_manager.h"

#include <boost/asio/post.hpp>

#include "simgate/morse/params_parser.h"
#include "simgate/core/config.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"
#include "simgate/core/text.h"
#include "simgate/morse/wire.h"

namespace simgate::socket {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;

namespace {

constexpr std::string_view k_failed = "FAILED";
constexpr std::string_view k_preempted = "PREEMPTED";
// `<id> simgate progress [on]`: the one request the transport answers itself
constexpr std::string_view k_simgate = "simgate";
constexpr std::string_view k_progress = "progress";
// Longest client id echoed in the reply to an oversized line (the line itself is dropped).
constexpr std::size_t k_max_echoed_id = 256;

// The options the JSON-RPC transport names differently were renamed (one name per knob on
// both TCP transports, issue #16); the old names stay accepted for one release.
constexpr kit::TcpOptions::Alias k_renamed[] = {{"max_connections", "max_clients"},
                                                {"max_message_bytes", "max_line_bytes"},
                                                {"max_unsent_bytes", "max_pending_replies_bytes"},
                                                {"max_in_flight", "max_pending_requests"}};

kit::TcpOptions tcp_defaults() {
  kit::TcpOptions o;
  o.port = 4000;
  o.max_connections = 1024;
  o.max_message_bytes = 1 << 20;
  o.max_unsent_bytes = 8 << 20;
  o.max_in_flight = 1024;
  return o;
}

}  // namespace

SocketOptions SocketOptions::parse(const json& options) {
  // every key read here, unknown keys refused by finish()
  ConfigObject config(options, "");
  SocketOptions o;
  o.success_word = config.get_choice("success_word", o.success_word, {"SUCCESS", "OK"});
  if (auto timeouts = config.get_object("timeouts")) {
    constexpr long long k_max_ms = 2'147'483'647;
    o.default_timeout = std::chrono::milliseconds(timeouts->get_int("default_ms", 0, 0, k_max_ms));
    if (auto services = timeouts->get_object("services")) {
      for (const auto& [name, value] : services->raw().items()) {
        const std::size_t dot = name.rfind('.');
        if (dot == std::string::npos || dot == 0 || dot + 1 == name.size())
          throw ConfigError(services->path_of(name) +
                            ": expected a service as \"component.service\" "
                            "(\"robot.waypoint.goto\"), found '" +
                            name + "'");
        o.service_timeouts.emplace(
            name, std::chrono::milliseconds(services->get_int(name, 0, 0, k_max_ms)));
      }
      services->finish();
    }
    timeouts->finish();
  }
  o.stream_port =
      static_cast<std::uint16_t>(config.get_int("stream_port", o.stream_port, 0, 65535));
  o.stream_queue = static_cast<std::size_t>(
      config.get_int("stream_queue", static_cast<long long>(o.stream_queue), 1, 100000));
  o.tcp = kit::TcpOptions::read(config, tcp_defaults(), "socket", k_renamed);
  o.tcp.finish(config);
  return o;
}

SocketRequestManager::SocketRequestManager(const json& options)
    : SocketRequestManager(SocketOptions::parse(options)) {}

SocketRequestManager::SocketRequestManager(SocketOptions o)
    : RequestManager("Socket service manager"),
      LineServer(name(), o.tcp),
      options_(std::move(o)),
      // bound now, so that a port in use fails the creation of the transport
      listener_(io_, name(), options_.tcp.host, options_.tcp.port),
      io_thread_(io_, name(), options_.tcp.io_spin),
      datastreams_(io_, name(), options_.tcp, options_.stream_port, options_.stream_queue) {
  limits_ = kit::ConnectionLimits::from(options_.tcp);
  // a client with max_in_flight requests unanswered waits for answers before more is read
  limits_.pause_at_unanswered = options_.tcp.max_in_flight;
  set_global_policy(options_.tcp.global_policy);
  set_progress_interval(options_.tcp.progress_interval);
  log::info(name(), " now listening on port ", listener_.port(), " (", listener_.endpoint(), ")");
}

SocketRequestManager::~SocketRequestManager() {
  stop();
  // the host stopped calling process(): finish what is left (replies go nowhere)
  abandon_pending("the socket transport has stopped");
}

void SocketRequestManager::start() {
  // a deadline for a service nobody can call here is likely a misspelt name
  for (const auto& [service, ms] : options_.service_timeouts) {
    const std::size_t dot = service.rfind('.');
    if (!may_call(service.substr(0, dot), service.substr(dot + 1)))
      log::warning(name(), ": timeouts.services: '", service,
                   "' is not a service clients may call here: its deadline applies to nothing");
  }
  // MORSE's socket datastreams: a port for each stream this transport carries, and the
  // services that say which (registered only when there is one, as MORSE does)
  datastreams_.open(streams(), transport_name(), *this);
  // the id "-" of the refusal matches no request: pymorse ignores the line, telnet shows it
  kit::TcpListener::Handlers handlers{
      [this](tcp::socket socket) { accept(std::move(socket)); },
      [this](const tcp::endpoint& peer) { return refusal_reason(peer); },
      [](const std::string& why) {
        std::string line;
        const json text = why;
        append_reply(line, "-", k_failed, &text);
        return line;
      }};
  // outcomes produced on the simulation thread come here: one flush per burst, then one
  // write per connection
  io_thread_.start(
      [this, handlers = std::move(handlers)]() mutable {
        deliver_on_this_thread([this] { asio::post(io_, [this] { flush_replies(); }); });
        listener_.start(std::move(handlers));
        datastreams_.start();
      },
      direct_reads());
}

void SocketRequestManager::on_services_changed() {
  // a robot spawned at run time may bring streams: their ports open on the I/O thread
  asio::post(io_, [this] { datastreams_.sync(); });
}

void SocketRequestManager::stop() {
  if (io_thread_.stop([this] { close_all(); }))
    deliver_on_any_thread();  // the connections are gone: outcomes from now on go nowhere
}

// The service port only: clients (and tests, and the banner) connect to the first endpoint;
// the stream ports are found through `simulation get_stream_port` and logged at start.
std::vector<std::string> SocketRequestManager::endpoints() const { return {listener_.endpoint()}; }

std::string SocketRequestManager::datastream_class(StreamDirection direction) const {
  return direction == StreamDirection::out ? "morse.middleware.socket_datastream.SocketPublisher"
                                           : "morse.middleware.socket_datastream.SocketReader";
}

void SocketRequestManager::close_all() {
  stopping_ = true;  // the requests still running end at shutdown (abandon_pending), not as cancels
  listener_.close();
  datastreams_.close_all();
  LineServer::close_all();
  requests_.clear();
}

void SocketRequestManager::accept(tcp::socket socket) {
  kit::LineServer& server = *this;
  const std::uint64_t number = next_session_++;
  client_arrived(number);
  add(std::make_shared<Session>(std::move(socket), server, limits_, name(), number));
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

void SocketRequestManager::on_messages_done(kit::Connection& connection, bool read_finished) {
  // half-way through a large read: its first half runs and is answered now only for a
  // client pipelining alone (read_split.h)
  if (read_finished)
    run_calls();  // answered at write_replies(), with the next read's replies if it is waiting
  else if (alone(connection))
    run_batch();
}

void SocketRequestManager::fail_in_order(Session& session, std::string_view id,
                                         std::string message) {
  const json text = std::move(message);
  reply_in_order(session, id, k_failed, &text);
}

void SocketRequestManager::reply_in_order(Session& session, std::string_view id,
                                          std::string_view status, const json* value) {
  // earlier requests of this read may run at once, answering them
  if (session.has_unanswered()) run_batch();
  scratch_.clear();
  append_reply(scratch_, id, status, value);
  if (!session.has_unanswered()) {
    session.send(scratch_);
    return;
  }
  // earlier requests are still with the core: the answer follows their outcomes, so that a
  // client reading replies in order (telnet, scripts) sees them in order
  session.defer_reply();
  // never one of requests_'s ids (kit::RequestSlots::k_mark)
  const RequestId reply_id = new_request_id();
  deferred_replies_.emplace(reply_id, DeferredReply{{session, session}, scratch_});
  answer_in_order(reply_id, Outcome{});
}

void SocketRequestManager::set_progress(Session& session, const RequestLine& request) {
  // `<id> simgate progress [true|false]`: no params means true
  json& params = progress_params_;
  if (!parse_params_into(request.params, request.params_column, params, params_error_)) {
    fail_in_order(session, request.id,
                  "Invalid request syntax: error while parsing the parameters at column " +
                      std::to_string(params_error_.column) + ": " + params_error_.error);
    return;
  }
  const json* on = nullptr;
  if (params.is_array() && params.size() == 1) on = &params[0];
  // `simgate progress true`: one bare value is that one parameter
  if (params.is_primitive() && !params.is_null()) on = &params;
  if (params.is_object() && params.size() == 1 && params.contains("on")) on = &params["on"];
  const bool none = params.is_null() || (params.is_array() && params.empty());
  if (!none && !on) {
    fail_in_order(
        session, request.id,
        "wrong # of parameters for service simgate.progress: expected at most 1 (on), got " +
            std::to_string(params.size()));
    return;
  }
  if (on && !on->is_boolean()) {
    fail_in_order(
        session, request.id,
        "wrong parameter type for service simgate.progress: parameter 'on' expects boolean, got " +
            describe_json(*on));
    return;
  }
  const bool enable = on ? on->get<bool>() : true;
  // the requests read after this line (earlier ones of this read kept their choice)
  session.set_wants_progress(enable);
  reply_in_order(session, request.id, options_.success_word, nullptr);
}

void SocketRequestManager::authenticate(Session& session, std::string_view line) {
  RequestLine request = parse_request_line(line);
  if (request.kind == RequestLine::Kind::blank) return;
  const std::optional<std::string_view> token = parse_auth_line(line);
  if (!token) {
    fail_in_order(session, request.id,
                  "Authentication required: send the line 'auth <token>' before any request "
                  "(the transport's \"auth\" option; docs/transports/socket.md#authentication)");
    return;
  }
  scratch_.clear();
  if (options_.tcp.auth.accepts(*token)) {
    session.set_authenticated();
    log::info(name(), ": ", session.label(), " authenticated");
    append_reply(scratch_, "auth", options_.success_word, nullptr);
    session.send(scratch_);
    return;
  }
  // one guess per connection
  log::warning(name(), ": ", session.label(), " presented a wrong token; connection closed");
  const json text = "wrong token: connection closed";
  append_reply(scratch_, "auth", k_failed, &text);
  session.send(scratch_);
  session.close("wrong token");
}

void SocketRequestManager::on_line(kit::LineConnection& connection, std::string_view line) {
  auto& session = static_cast<Session&>(connection);
  if (!session.authenticated()) [[unlikely]] {
    authenticate(session, line);
    return;
  }
  RequestLine request = parse_request_line(line);
  switch (request.kind) {
    case RequestLine::Kind::blank: return;
    case RequestLine::Kind::malformed:
      fail_in_order(session, request.id, std::move(request.error));
      return;
    case RequestLine::Kind::cancel:
      // no reply of its own: the request ends PREEMPTED; unknown ids are ignored (as MORSE)
      if (const kit::IdTable::Entry* pending = session.find_pending(request.id)) {
        const RequestId id = pending->id;  // read before run_batch() changes the table
        run_batch();                       // the request may be in this read's batch
        cancel(id);
      }
      return;
    case RequestLine::Kind::call: break;
  }
  // the transport's own request: progress lines for this connection (opt-in)
  if (request.component == k_simgate && request.service == k_progress) [[unlikely]] {
    set_progress(session, request);
    return;
  }

  // one pending request per id and connection, or replies could not be told apart
  kit::IdTable::Entry* pending = session.add_pending(request.id);
  if (!pending) {
    fail_in_order(
        session, request.id,
        "Request id '" + std::string(request.id) +
            "' is already pending on this connection: wait for its reply or use another id");
    return;
  }

  // the next call of this read, in an object an earlier read left (its strings and
  // parameter array are refilled: no allocation)
  if (batch_count_ == batch_.size()) batch_.emplace_back();
  auto& [id, call] = batch_[batch_count_];
  if (!parse_params_into(request.params, request.params_column, call.params, params_error_)) {
    session.drop_pending(request.id);
    fail_in_order(session, request.id,
                  params_error_.example.empty()
                      ? "Invalid request syntax: error while parsing the parameters at column " +
                            std::to_string(params_error_.column) + ": " + params_error_.error
                      // `set_speed 0.5 0.2`: bare values where a list belongs
                      : "Invalid request syntax: parameters must be a list, e.g. `" +
                            params_error_.example + "`");
    return;
  }
  if (requests_.size() >= decltype(requests_)::k_max_live) {
    session.drop_pending(request.id);
    fail_in_order(session, request.id,
                  "Too many requests are waiting for their outcome in this server: retry later");
    return;
  }

  // the request's slot: its id says where the reply goes
  id = requests_.insert({&session, pending->hash});
  pending->id = id;
  // a pipelining client names the same service line after line
  if (!same_text(call.component, request.component)) call.component.assign(request.component);
  if (!same_text(call.service, request.service)) call.service.assign(request.service);
  call.progress = session.wants_progress();
  call.client = session.number();
  call.timeout = timeout_for(call.component, call.service);
  // handed to the core with the rest of this read (on_messages_done)
  ++batch_count_;
}

std::chrono::milliseconds SocketRequestManager::timeout_for(const std::string& component,
                                                            const std::string& service) {
  if (options_.service_timeouts.empty()) return options_.default_timeout;
  timeout_key_.assign(component).append(1, '.').append(service);  // no allocation once grown
  auto it = options_.service_timeouts.find(timeout_key_);
  return it == options_.service_timeouts.end() ? options_.default_timeout : it->second;
}

void SocketRequestManager::on_oversized_line(kit::LineConnection& connection,
                                             std::string_view prefix, std::size_t /*bytes*/) {
  auto& session = static_cast<Session&>(connection);
  // answer with the line's id when it has a usable one, "-" otherwise
  std::size_t begin = 0;
  while (begin < prefix.size() && (prefix[begin] == ' ' || prefix[begin] == '\t')) ++begin;
  std::size_t end = begin;
  while (end < prefix.size() && prefix[end] != ' ' && prefix[end] != '\t' && prefix[end] != '\r')
    ++end;
  std::string_view id = prefix.substr(begin, end - begin);
  if (id.empty() || id.size() > k_max_echoed_id || end == prefix.size() || !echoable_id(id))
    id = "-";
  log::warning(name(), ": ", session.label(), ": request line longer than ",
               limits_.max_message_bytes, " bytes ignored");
  fail_in_order(session, id,
                "Request too long: the line exceeds " + std::to_string(limits_.max_message_bytes) +
                    " bytes (" + limits_.message_bytes_key + "); it was ignored");
}

void SocketRequestManager::on_input_ended(kit::LineConnection& connection) {
  // the client will send nothing more: under "cancel" it has left, and its async requests
  // end (PREEMPTED, written if it still reads); sync ones are answered as usual
  cancel_requests_of(static_cast<Session&>(connection));
}

void SocketRequestManager::on_closed(kit::Connection& connection) {
  auto& session = static_cast<Session&>(connection);
  cancel_requests_of(session);
  // its outcomes have nowhere to go: forget them
  session.pending().for_each([this](const kit::IdTable::Entry& e) { requests_.erase(e.id); });
  session.clear_pending();
  client_left(session.number());
}

void SocketRequestManager::cancel_requests_of(const Session& session) {
  if (!options_.tcp.cancel_on_disconnect || stopping_) return;
  // every unanswered request: a cancel finds the async ones that run (sync ones are not
  // cancellable, and end as usual). Calls of the read being handled have not reached the
  // core yet: they are cancelled after it (run_calls).
  const bool batch_open = batch_count_ > 0;
  session.pending().for_each([&](const kit::IdTable::Entry& e) {
    if (batch_open)
      cancel_after_batch_.push_back(e.id);
    else
      cancel(e.id);
  });
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
    if (Session* s = reply.session.get()) s->queue_deferred_reply(reply.line);
  } catch (const std::exception& e) {
    log::error(name(), ": cannot queue an error reply: ", e.what());
  }
}

void SocketRequestManager::on_service_progress(RequestId id, json&& value) {
  // the I/O thread, like outcomes: before the request's reply, never after it
  if (!(id & decltype(requests_)::k_mark)) return;
  const Pending* entry = requests_.find(id);
  if (!entry || entry->session->closed()) return;
  entry->session->report_progress(entry->client_id_hash, id, value);
}

void SocketRequestManager::flush_replies() {
  deliver_handed_over();
  flush_touched();
}

void SocketRequestManager::deliver(RequestId id, const Outcome& outcome) try {
  const Pending* entry = requests_.find(id);
  if (!entry) return;  // its client is gone
  const Pending pending = *entry;
  requests_.erase(id);  // first: the reply may close the connection, which erases its entries
  Session& session = *pending.session;

  std::string_view status = options_.success_word;
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
                         "success_word", "max_connections", "max_message_bytes", "max_unsent_bytes",
                         "max_in_flight", "io_spin_us", "global_policy", "on_disconnect",
                         "idle_timeout_s", "idle_evict_s", "line_timeout_s", "max_buffered_bytes",
                         "max_connections_per_peer", "auth", "progress_interval_ms", "timeouts",
                         "stream_port", "stream_queue",
                         // deprecated names: accepted with a warning until the next release
                         "max_clients", "max_line_bytes", "max_pending_replies_bytes",
                         "max_pending_requests")
