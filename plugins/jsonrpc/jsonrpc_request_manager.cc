#include "jsonrpc_request_manager.h"

#include <algorithm>
#include <cstring>
#include <exception>
#include <iterator>
#include <stdexcept>

#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>

#include "protocol.h"
#include "simgate/core/config.h"
#include "simgate/core/errors.h"
#include "simgate/kit/id_table.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"

namespace simgate::jsonrpc {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;

namespace {
constexpr std::string_view k_version = "0.1.0";
constexpr std::size_t k_read_chunk = 64 * 1024;
// a burst of replies is written early once this much is queued
constexpr std::size_t k_coalesce_bytes = 256 * 1024;

json result_response(const json& id, json result) {
  return {{"jsonrpc", "2.0"}, {"id", id}, {"result", std::move(result)}};
}
}  // namespace

// ---------------------------------------------------------------------------------------
// Options

Options Options::parse(const json& options) {
  ConfigObject config(options.is_null() ? json::object() : options, "");
  kit::TcpOptions defaults;
  defaults.port = 4001;
  defaults.max_message_bytes = 8u << 20;
  defaults.max_unsent_bytes = 16u << 20;
  defaults.max_connections = 512;
  defaults.max_in_flight = 1024;
  Options o;
  o.tcp = kit::TcpOptions::read(config, defaults, "jsonrpc");
  o.max_depth = static_cast<std::size_t>(config.get_int("max_depth", static_cast<long long>(o.max_depth), 2, 10000));
  o.tcp.finish(config);
  return o;
}

// ---------------------------------------------------------------------------------------
// Session: one connection. Reads lines, hands them to the manager, writes replies.

class JsonRpcRequestManager::Session : public std::enable_shared_from_this<Session> {
 public:
  Session(JsonRpcRequestManager& owner, tcp::socket socket)
      : owner_(owner), socket_(std::move(socket)), read_buf_(k_read_chunk) {
    error_code ec;
    auto ep = socket_.remote_endpoint(ec);
    peer_ = ec ? std::string("unknown peer") : kit::to_string(ep);
  }

  const std::string& peer() const { return peer_; }
  bool closed() const { return closed_; }

  void start() {
    // writes are tried at once (write_now); reads stay asynchronous
    socket_.non_blocking(true);
    read();
  }

  // Queues one line (a newline is added) and writes what the kernel accepts at once.
  // Bytes the kernel refused are the backlog: reading pauses when it passes half of
  // max_unsent_bytes, and a reply that finds more than max_unsent_bytes already waiting
  // closes the connection (the client does not read).
  void send(std::string_view line) {
    if (closed_) return;
    const std::size_t waiting = out_.size() + writing_.size();
    if (waiting > owner_.options_.tcp.max_unsent_bytes) {
      close("it does not read its replies (" + std::to_string(waiting) + " bytes unsent, max_unsent_bytes " +
            std::to_string(owner_.options_.tcp.max_unsent_bytes) + ")");
      return;
    }
    out_.append(line);
    out_.push_back('\n');
    if (!write_active_) {
      if (owner_.deferring_writes_ && out_.size() < k_coalesce_bytes) {
        // coalesced: written once the current burst of replies is complete
        if (!dirty_) {
          dirty_ = true;
          owner_.dirty_.push_back(shared_from_this());
        }
      } else {
        write_now();
      }
    }
    if (out_.size() + writing_.size() > owner_.options_.tcp.max_unsent_bytes / 2) paused_ = true;
  }

  // Writes what send() deferred (end of a burst).
  void flush() {
    dirty_ = false;
    if (closed_ || write_active_) return;
    write_now();
    maybe_finish();
  }

  // ---- pending calls (ids scoped to this connection) ----
  std::size_t in_flight() const { return in_flight_; }
  void add_in_flight() { ++in_flight_; }
  bool has_id(const std::string& key) const { return calls_.find(key) != nullptr; }
  void track(const std::string& key, RequestId id) {
    if (kit::IdTable::Entry* entry = calls_.insert(key)) entry->id = id;
  }
  std::optional<RequestId> find(const std::string& key) const {
    const kit::IdTable::Entry* entry = calls_.find(key);
    if (!entry) return std::nullopt;
    return entry->id;
  }
  // A pending call (or cancel) produced its reply.
  void done(const std::string& key) {
    if (!key.empty()) calls_.erase(key);
    if (in_flight_ > 0) --in_flight_;
    maybe_finish();
  }
  // The calls to cancel when the client leaves.
  std::vector<RequestId> take_calls() {
    std::vector<RequestId> ids;
    ids.reserve(calls_.size());
    calls_.for_each([&](const kit::IdTable::Entry& e) { ids.push_back(e.id); });
    return ids;
  }

  // ---- while the manager watches it (kit::DirectReads, simgate/kit/idle_spin.h)
  // Reads what is waiting, without waiting, and handles it; false when nothing was.
  bool read_now() {
    if (closed_) return false;
    error_code ec;
    const std::size_t n = socket_.read_some(asio::buffer(read_buf_), ec);
    if (ec == asio::error::would_block || ec == asio::error::try_again) return false;
    on_read(ec, n);
    return true;
  }
  // No longer watched: waits for the next bytes through the event loop.
  void read_async() {
    if (closed_) return;
    socket_.async_read_some(asio::buffer(read_buf_),
                            [self = shared_from_this()](const error_code& ec, std::size_t n) {
                              self->on_read(ec, n);
                            });
  }

  void close(const std::string& reason) {
    if (closed_) return;
    closed_ = true;
    log::debug("jsonrpc: closing connection from ", peer_, ": ", reason);
    error_code ec;
    socket_.shutdown(tcp::socket::shutdown_both, ec);
    socket_.close(ec);
    owner_.session_closed(*this);
  }

 private:
  void read() {
    if (closed_ || reading_ || paused_ || eof_) return;
    reading_ = true;
    if (owner_.watch(*this)) return;  // the polling I/O thread reads the socket itself (read_now)
    read_async();
  }

  void on_read(const error_code& ec, std::size_t n) {
    // reading_ stays true while read_buf_ is being parsed: nothing may start another read
    // into it until then (replies written meanwhile may try to resume reading)
    if (closed_ || ec) reading_ = false;
    if (closed_) return;
    try {
      if (ended(ec)) return;
      // every message of this read: calls handed over together, replies written together
      error_code next;  // how the last read on below ended (eof or an error: after the burst)
      {
        struct Burst {
          JsonRpcRequestManager& m;
          ~Burst() {
            try {
              m.flush_submissions();
              m.flush_writes();
            } catch (const std::exception& e) {
              m.deferring_writes_ = false;
              log::error("jsonrpc: ", e.what());
            }
          }
        } burst{owner_};
        owner_.deferring_writes_ = true;
        split_lines(read_buf_.data(), n);
        // a large read of a client pipelining alone (read_split.h): while it has sent more
        // already, read on (the socket is non-blocking) and write the replies of these reads
        // together, one write per read fewer; a short read is answered at once
        for (int reads = 1; reads < k_reads_in_a_row && n >= kit::ReadSplit::k_min_bytes; ++reads) {
          if (closed_ || paused_ || !owner_.read_split_.alone(this)) break;
          owner_.flush_submissions();  // this read's calls run before the next read's
          n = socket_.read_some(asio::buffer(read_buf_), next);
          if (next) break;
          split_lines(read_buf_.data(), n);
        }
        owner_.read_split_.alone(this);  // notes the read (who else is sending)
      }
      reading_ = false;
      if (next != asio::error::would_block && next != asio::error::try_again && ended(next)) return;
      read();
    } catch (const std::exception& e) {
      reading_ = false;
      // nothing escapes an Asio handler; the server keeps serving everyone else
      log::error("jsonrpc: connection from ", peer_, ": ", e.what());
      close(std::string("internal error: ") + e.what());
    }
  }

  // A read that brought the end of input (answer what is left, then close) or an error
  // (close); false for a read that brought bytes.
  bool ended(const error_code& ec) {
    if (ec == asio::error::eof) {
      on_eof();
      return true;
    }
    if (ec) {
      close("read failed: " + ec.message());
      return true;
    }
    return false;
  }

  // Reads in a row of a client pipelining alone before going back to the event loop.
  static constexpr int k_reads_in_a_row = 4;

  // Splits received bytes into lines; keeps a partial line for the next read.
  void split_lines(const char* p, std::size_t n) {
    const char* end = p + n;
    const std::size_t max = owner_.options_.tcp.max_message_bytes;
    // a large read from a client pipelining alone: its first half runs and is answered
    // before the rest is parsed (simgate/kit/read_split.h)
    const char* half = n >= kit::ReadSplit::k_min_bytes ? p + n / 2 : nullptr;
    while (p < end && !closed_) {
      if (half && p >= half) {
        half = nullptr;
        if (owner_.read_split_.alone(this)) {
          owner_.flush_submissions();
          owner_.flush_writes();
          owner_.deferring_writes_ = true;
          // those replies may have closed the connection (the client does not read them):
          // the rest of the read is dropped, not run for a client that is gone
          if (closed_) return;
        }
      }
      const char* nl = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
      if (!nl) {
        if (!discarding_) {
          partial_.append(p, end);
          if (partial_.size() > max) too_large(partial_.size());
        }
        return;
      }
      if (discarding_) {
        // the rest of an oversized message: already answered
        discarding_ = false;
      } else if (partial_.empty()) {
        owner_.handle_message(shared_from_this(), std::string_view(p, static_cast<std::size_t>(nl - p)));
      } else {
        partial_.append(p, nl);
        std::string line;
        line.swap(partial_);
        owner_.handle_message(shared_from_this(), line);
      }
      p = nl + 1;
    }
  }

  void too_large(std::size_t size) {
    partial_.clear();
    partial_.shrink_to_fit();
    discarding_ = true;
    const auto max = owner_.options_.tcp.max_message_bytes;
    send(dump(error_response(nullptr, code::invalid_request,
                             "Invalid Request: message exceeds max_message_bytes (" + std::to_string(max) + ")",
                             json{{"reason", "message too large"}, {"bytes_so_far", size}, {"max_message_bytes", max}})));
  }

  // The client will send nothing more: answer a last line without newline, apply the
  // disconnect policy, and close once every reply is out.
  void on_eof() {
    eof_ = true;
    if (!partial_.empty() && !discarding_) {
      std::string line;
      line.swap(partial_);
      owner_.handle_message(shared_from_this(), line);
      owner_.flush_submissions();
    }
    if (owner_.options_.tcp.cancel_on_disconnect)
      for (RequestId id : take_calls()) owner_.cancel(id);
    maybe_finish();
  }

  void maybe_finish() {
    if (!closed_ && eof_ && in_flight_ == 0 && out_.empty() && !write_active_) close("client closed the connection");
  }

  // A non-blocking write of out_ now, then an async write of what the kernel refused.
  void write_now() {
    if (!out_.empty()) {
      error_code ec;
      const std::size_t n = socket_.write_some(asio::buffer(out_), ec);
      if (ec && ec != asio::error::would_block && ec != asio::error::try_again) {
        close("write failed: " + ec.message());
        return;
      }
      out_.erase(0, ec ? 0 : n);
    }
    if (out_.empty()) {
      resume_reading();
      return;
    }
    writing_.clear();
    writing_.swap(out_);
    write_active_ = true;
    asio::async_write(socket_, asio::buffer(writing_), [self = shared_from_this()](const error_code& ec, std::size_t) {
      self->on_write(ec);
    });
  }

  void on_write(const error_code& ec) {
    write_active_ = false;
    writing_.clear();
    if (closed_) return;
    if (ec) {
      close("write failed: " + ec.message());
      return;
    }
    write_now();
    if (closed_) return;
    maybe_finish();
  }

  // Reading resumes once the backlog is gone.
  void resume_reading() {
    if (paused_ && out_.empty() && !write_active_) {
      paused_ = false;
      read();
    }
  }

  JsonRpcRequestManager& owner_;                   // outlives every session (stop() joins)
  tcp::socket socket_;                             // the connection
  std::string peer_;                               // "127.0.0.1:53122", for logs
  std::vector<char> read_buf_;                     // one read
  std::string partial_;                            // an incomplete line
  bool discarding_ = false;                        // skipping the rest of an oversized line
  bool reading_ = false;                           // a read is in flight
  bool paused_ = false;                            // not reading: too many unsent bytes
  bool eof_ = false;                               // the client sent FIN
  bool closed_ = false;                            // socket closed, manager told
  std::string out_;                                // replies waiting for the next write
  std::string writing_;                            // the bytes of the write in flight
  bool write_active_ = false;                      // a write is in flight
  bool dirty_ = false;                             // listed in the manager's dirty_
  // dumped JSON-RPC id -> pending request
  kit::IdTable calls_;
  std::size_t in_flight_ = 0;                      // pending calls, notifications and cancels
};

// A batch: the responses collected in entry order, sent as one array when all are in. Its
// reply is bounded: once the responses stored reach max_unsent_bytes, each later entry
// answers a short -32006 instead of its result (issue #17: a batch of rpc.discover built a
// 222 MB reply).
struct JsonRpcRequestManager::Batch {
  Batch(std::size_t n, std::size_t max_bytes) : responses(n), remaining(n), max_bytes(max_bytes) {}
  std::vector<std::string> responses;  // serialised; empty = no response (notification)
  std::size_t remaining;               // entries not yet finished
  std::size_t bytes = 0;               // of the responses stored so far
  std::size_t max_bytes;               // the connection's max_unsent_bytes
  bool full() const { return bytes >= max_bytes; }
};

// ---------------------------------------------------------------------------------------
// JsonRpcRequestManager

JsonRpcRequestManager::JsonRpcRequestManager(const json& options)
    : RequestManager("JSON-RPC service manager"),
      options_(Options::parse(options)),
      // bound now, so that a port in use fails the creation of the transport
      listener_(io_, name(), options_.tcp.host, options_.tcp.port),
      io_thread_(io_, name(), options_.tcp.io_spin) {
  set_global_policy(options_.tcp.global_policy);
}

JsonRpcRequestManager::~JsonRpcRequestManager() { stop(); }

std::vector<std::string> JsonRpcRequestManager::endpoints() const { return {listener_.endpoint()}; }

void JsonRpcRequestManager::start() {
  const std::string why = "too many connections (max_connections " + std::to_string(options_.tcp.max_connections) + ")";
  kit::TcpListener::Handlers handlers{[this](tcp::socket socket) { accept(std::move(socket)); },
                                      [this] { return sessions_.size() >= options_.tcp.max_connections; }, why,
                                      dump(error_response(nullptr, code::overloaded, "Overloaded: " + why)) + "\n"};
  // outcomes produced on the simulation thread come here: one drain per burst, then one
  // write per connection
  if (io_thread_.start(
          [this, handlers = std::move(handlers)]() mutable {
            deliver_on_this_thread([this] { asio::post(io_, [this] { drain_completions(); }); });
            listener_.start(std::move(handlers));
          },
          direct_))
    log::info("jsonrpc: listening on ", endpoints().front());
}

void JsonRpcRequestManager::stop() {
  if (!io_thread_.stop([this] { shutdown_io(); })) return;
  deliver_on_any_thread();  // the connections are gone: outcomes from now on go nowhere
  // finish what the core still holds (replies can no longer be sent)
  abandon_pending();
}

void JsonRpcRequestManager::shutdown_io() {
  stopping_ = true;
  listener_.close();
  auto sessions = sessions_;
  for (const auto& s : sessions) s->close("server stopping");
  sessions_.clear();
  client_count_.store(0, std::memory_order_relaxed);
}

void JsonRpcRequestManager::accept(tcp::socket socket) {
  auto session = std::make_shared<Session>(*this, std::move(socket));
  sessions_.insert(session);
  client_count_.store(sessions_.size(), std::memory_order_relaxed);
  log::debug("jsonrpc: connection from ", session->peer());
  session->start();
}

bool JsonRpcRequestManager::watch(Session& session) {
  // only while the I/O thread polls (never with io_spin_us 0), for a client sending alone:
  // others are served by the event loop between direct reads
  if (options_.tcp.io_spin.count() <= 0 || !read_split_.alone(&session)) return false;
  direct_.watch(session.shared_from_this());
  return true;
}

void JsonRpcRequestManager::session_closed(Session& session) {
  direct_.forget(session);
  auto self = session.shared_from_this();
  sessions_.erase(self);
  client_count_.store(sessions_.size(), std::memory_order_relaxed);
  if (stopping_ || !options_.tcp.cancel_on_disconnect) return;
  // the client is gone: its pending calls end (their replies are dropped)
  for (RequestId id : session.take_calls()) cancel(id);
}

void JsonRpcRequestManager::handle_message(const std::shared_ptr<Session>& session, std::string_view line) {
  // framing: optional "\r" before the "\n"; blank lines are keep-alives
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (line.find_first_not_of(" \t\r") == std::string_view::npos) return;

  ReplyTo single{session, nullptr, false, nullptr, 0};
  if (line.size() > options_.tcp.max_message_bytes) {
    reply(single, error_response(nullptr, code::invalid_request,
                                 "Invalid Request: message exceeds max_message_bytes (" +
                                     std::to_string(options_.tcp.max_message_bytes) + ")",
                                 json{{"reason", "message too large"}, {"bytes", line.size()}}));
    return;
  }
  // the common shape (one plain request object) without a DOM; anything else, errors
  // included, takes the full path below
  if (parse_request_fast(line, options_.max_depth, request_)) {
    dispatch(session, request_, std::move(single));
    return;
  }
  if (json_nests_deeper_than(line, options_.max_depth)) {
    reply(single, error_response(nullptr, code::invalid_request,
                                 "Invalid Request: message nests deeper than max_depth (" +
                                     std::to_string(options_.max_depth) + ")",
                                 json{{"reason", "nesting too deep"}}));
    return;
  }
  json message;
  try {
    message = json::parse(line.begin(), line.end());
  } catch (const json::exception& e) {
    // parse_error, and out_of_range for numbers beyond a double ("1e400")
    reply(single, error_response(nullptr, code::parse_error, "Parse error", json{{"reason", e.what()}}));
    return;
  }

  if (message.is_array()) {
    if (message.empty()) {
      reply(single, error_response(nullptr, code::invalid_request, "Invalid Request: empty batch",
                                   json{{"reason", "a batch must contain at least one request"}}));
      return;
    }
    // every entry counts against max_in_flight, whatever it is (rpc.*, invalid entries):
    // a batch larger than the room left is refused whole, with one error (issue #17: a
    // 2 MB batch of `1`s built a million error objects on the I/O thread)
    const std::size_t room = options_.tcp.max_in_flight - std::min(session->in_flight(), options_.tcp.max_in_flight);
    if (message.size() > room) {
      reply(single, error_response(nullptr, code::overloaded,
                                   "Overloaded: a batch of " + std::to_string(message.size()) + " entries, " +
                                       std::to_string(room) + " more calls allowed in flight on this connection (max_in_flight " +
                                       std::to_string(options_.tcp.max_in_flight) + ")",
                                   json{{"batch_entries", message.size()}, {"max_in_flight", options_.tcp.max_in_flight}}));
      return;
    }
    // every entry answers into the batch; the array goes out when the last one is in
    auto batch = std::make_shared<Batch>(message.size(), options_.tcp.max_unsent_bytes);
    for (std::size_t i = 0; i < message.size(); ++i)
      handle_request(session, message[i], ReplyTo{session, nullptr, false, batch, i});
    return;
  }
  handle_request(session, message, single);
}

void JsonRpcRequestManager::flush_submissions() {
  // one hand-over per read: a batch's calls always travel together, so they run in the
  // same process(); when the simulation lock is free they run here, on this thread, and
  // their replies are queued on their connections before run_or_submit returns
  if (to_submit_count_ == 0) return;
  // the call objects stay for the next read's requests (their arrays circulate with
  // request_'s params: no allocation per request), at most k_kept_calls of them
  run_or_submit(std::span(to_submit_.data(), to_submit_count_), /*refilled=*/true);
  to_submit_count_ = 0;
  if (to_submit_.size() > k_kept_calls) to_submit_.erase(to_submit_.begin() + k_kept_calls, to_submit_.end());
}

void JsonRpcRequestManager::flush_writes() {
  deferring_writes_ = false;
  auto dirty = std::move(dirty_);
  dirty_.clear();
  for (const auto& s : dirty) s->flush();
}

void JsonRpcRequestManager::handle_request(const std::shared_ptr<Session>& session, json& message,
                                           ReplyTo to) {
  // validate; invalid requests are answered even without an id
  Request request;
  if (auto error = parse_request(message, request)) {
    to.id = (*error)["id"];
    reply(to, std::move(*error));
    return;
  }
  dispatch(session, request, std::move(to));
}

void JsonRpcRequestManager::dispatch(const std::shared_ptr<Session>& session, Request& request, ReplyTo to) {
  to.id = request.id;
  to.notification = !request.has_id;

  // reserved methods run here, on the I/O thread
  const std::string& method = request.method;
  if (method == "rpc.cancel" || method == "$/cancelRequest") {
    handle_cancel(session, method, request.params, std::move(to));
    return;
  }
  if (method == "rpc.discover") {
    if (to.batch && to.batch->full()) {
      reply(to, std::nullopt);  // answered -32006 by reply(): the document is not even built
      return;
    }
    reply(to, result_response(to.id, openrpc_document(descriptors(), k_version,
                                                      global_policy() == GlobalPolicy::preempt ? "preempt" : "reject")));
    return;
  }
  std::string component, service;
  if (method.rfind("rpc.", 0) == 0 || !split_method(method, component, service)) {
    const std::string reason = method.rfind("rpc.", 0) == 0
                                   ? "'" + method + "' is not a method of this server (rpc.* is reserved)"
                                   : "'" + method + "' is not of the form 'component.service'";
    reply(to, error_response(to.id, code::method_not_found, "Method not found: " + reason,
                             json{{"method", method}, {"reason", reason}}));
    return;
  }

  // limits: calls in flight on this connection, ids unique among them
  if (session->in_flight() >= options_.tcp.max_in_flight) {
    if (to.notification) log::debug("jsonrpc: ", session->peer(), ": notification ", method, " dropped: overloaded");
    reply(to, error_response(to.id, code::overloaded,
                             "Overloaded: " + std::to_string(session->in_flight()) +
                                 " calls in flight on this connection (max_in_flight " +
                                 std::to_string(options_.tcp.max_in_flight) + ")",
                             json{{"method", method}, {"max_in_flight", options_.tcp.max_in_flight}}));
    return;
  }
  std::string key;
  if (request.has_id && !request.id.is_null()) {
    key = request.id_text.empty() ? dump(request.id) : std::move(request.id_text);
    if (session->has_id(key)) {
      reply(to, error_response(to.id, code::invalid_request,
                               "Invalid Request: id " + key + " is already used by a pending call on this connection",
                               json{{"method", method}, {"reason", "duplicate id"}}));
      return;
    }
  }

  // gathered; flush_submissions() hands the calls of this read to the core together
  const RequestId id = new_request_id();
  if (!key.empty()) session->track(key, id);
  session->add_in_flight();
  if (to_submit_count_ == to_submit_.size()) to_submit_.emplace_back();
  auto& [call_id, call] = to_submit_[to_submit_count_++];
  call_id = id;
  if (call.component != component) call.component.swap(component);
  if (call.service != service) call.service.swap(service);
  call.params.swap(request.params);  // request_ takes the call's old array, for the next parse
  Pending& pending = pending_.try_emplace(id).first->second;  // a recycled node when there is one
  pending.to = std::move(to);
  pending.method.assign(method);
  pending.id_key.assign(key);
  pending.cancel = false;
}

void JsonRpcRequestManager::handle_cancel(const std::shared_ptr<Session>& session, const std::string& method,
                                          const json& params, ReplyTo to) {
  // {"id": X} or [X]
  const json* target = nullptr;
  if (params.is_object() && params.contains("id")) target = &params["id"];
  if (params.is_array() && params.size() == 1) target = &params[0];
  if (!target || !(target->is_string() || target->is_number())) {
    reply(to, error_response(to.id, code::invalid_params,
                             "Invalid params: " + method + " takes {\"id\": <id of one of your pending calls>}",
                             json{{"method", method}, {"parameter", "id"}}));
    return;
  }
  // calls read before this cancel reach the simulation thread first (inside a batch the
  // batch's calls stay together: a cancel there sees the calls of earlier messages only)
  if (!to.batch) flush_submissions();
  const auto id = session->find(dump(*target));
  if (!id) {
    reply(to, result_response(to.id, false));
    return;
  }
  // the answer comes once the cancel ran, through the same list as outcomes, so it keeps
  // its place among the replies (before the cancelled call's -32002)
  const RequestId cancel_id = new_request_id();
  session->add_in_flight();
  Pending& pending = pending_.try_emplace(cancel_id).first->second;
  pending.to = std::move(to);
  pending.method.assign(method);
  pending.id_key.clear();
  pending.cancel = true;
  cancel(*id, [this, cancel_id](bool found) { complete_request(cancel_id, Outcome::success(json(found))); });
}

void JsonRpcRequestManager::on_service_completion(RequestId id, Outcome&& outcome) {
  // the I/O thread (deliver_on_this_thread): inside run_or_submit, or drain_completions()
  finish_call(id, std::move(outcome));
}

void JsonRpcRequestManager::drain_completions() {
  // replies of the whole burst go out with one write per connection
  deferring_writes_ = true;
  deliver_handed_over();
  flush_writes();
}

void JsonRpcRequestManager::finish_call(RequestId id, Outcome&& outcome) {
  auto it = pending_.find(id);
  if (it == pending_.end()) return;
  // taken out of the table while it is answered; its node is given back for a later call
  struct GiveBack {
    decltype(pending_)& table;
    decltype(pending_)::node_type node;
    ~GiveBack() { table.recycle(std::move(node)); }
  } entry{pending_, pending_.extract(it)};
  Pending& pending = entry.node.mapped();
  auto session = pending.to.session.lock();
  // nobody to answer: skip serialising (results can be large)
  if (!session || session->closed()) return;
  try {
    if (pending.cancel) {
      // rpc.cancel's own answer: true if the call was still running
      reply(pending.to, result_response(pending.to.id, outcome.value ? std::move(*outcome.value) : json(false)));
    } else if (outcome.status == Status::success) {
      static const json k_no_result;  // null
      if (pending.to.batch)
        reply(pending.to, result_response(pending.to.id, outcome.value ? std::move(*outcome.value) : json(nullptr)));
      else if (!pending.to.notification) {
        // the envelope by hand around the result; id_key is dump(id) ("" for a null id)
        line_.clear();
        append_result_line(line_, pending.id_key.empty() ? std::string_view("null") : pending.id_key,
                           outcome.value ? *outcome.value : k_no_result);
        session->send(line_);
        if (line_.capacity() > k_coalesce_bytes) std::string().swap(line_);  // keep no large buffer
      }
    } else {
      reply(pending.to, outcome_response(pending.to.id, outcome, pending.method));
    }
  } catch (const std::exception& e) {
    log::error("jsonrpc: reply to ", pending.method, ": ", e.what());
  }
  session->done(pending.id_key);
}

void JsonRpcRequestManager::reply(ReplyTo& to, std::optional<json> response) {
  if (to.batch) {
    auto& batch = *to.batch;
    if (!to.notification) {
      std::string text;
      if (response && !batch.full()) text = dump(*response);
      if (!response || batch.bytes + text.size() > batch.max_bytes) {
        // past the batch's byte budget: a short error instead (counted, so the reply stays
        // within max_unsent_bytes plus one such line per entry)
        batch.bytes = std::max(batch.bytes, batch.max_bytes);
        text = dump(error_response(to.id, code::overloaded,
                                   "Overloaded: the batch's reply exceeds max_unsent_bytes (" +
                                       std::to_string(batch.max_bytes) + "); this entry's response was dropped",
                                   json{{"max_unsent_bytes", batch.max_bytes}}));
      }
      batch.bytes += text.size();
      batch.responses[to.index] = std::move(text);
    }
    if (--batch.remaining > 0) return;
    // the last entry: send what the batch answers, nothing if it held only notifications
    std::string array;
    for (auto& r : batch.responses) {
      if (r.empty()) continue;
      array += array.empty() ? '[' : ',';
      array += r;
    }
    auto session = to.session.lock();
    if (session && !array.empty()) session->send(array + "]");
    return;
  }
  if (to.notification || !response) return;
  if (auto session = to.session.lock()) session->send(dump(*response));
}

}  // namespace simgate::jsonrpc

SIMGATE_TRANSPORT_PLUGIN(jsonrpc, simgate::jsonrpc::JsonRpcRequestManager, "0.1.0", "host", "port",
                         "max_message_bytes", "max_depth", "max_in_flight", "max_unsent_bytes",
                         "max_connections", "io_spin_us", "on_disconnect", "global_policy")
