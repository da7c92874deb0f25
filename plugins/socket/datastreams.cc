// datastreams.cc — MORSE's socket datastreams (datastreams.h): the stream ports, their
// connections, the samples written out, the commands read in, and the three `simulation`
// services that say where the streams are.
#include "datastreams.h"

#include <algorithm>

#include <boost/asio/post.hpp>

#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/morse/wire.h"

namespace simgate::socket {

namespace asio = boost::asio;
using asio::ip::tcp;

namespace {

// MORSE's datastream port range starts at 60000 and ends with the ports; a port in use is
// skipped for the next one, at most this many times per stream (a range that busy means
// something else is wrong: the error names the last port tried).
constexpr int k_port_attempts = 100;

// What a command of `info` looks like, for messages: {"v": ..., "w": ...}.
std::string command_example(const StreamInfo& info) {
  std::string keys;
  for (const auto& f : info.fields) keys += (keys.empty() ? "\"" : ", \"") + f + "\": ...";
  return "{" + keys + "}";
}

}  // namespace

// One client of a stream port.
class Datastreams::Connection : public kit::LineConnection {
 public:
  Connection(tcp::socket socket, kit::LineServer& server, const kit::ConnectionLimits& limits,
             Port& port, std::uint64_t number)
      : LineConnection(std::move(socket), server, limits, port.who, number), port(port) {}

  Port& port;                                        // its stream
  std::shared_ptr<StreamSubscription> subscription;  // output stream: its queue of samples
  bool writing = false;                              // input stream: counted in port.writers
  bool warned_malformed = false;  // a line it sent was not a command (logged once)
};

Datastreams::Datastreams(asio::io_context& io, std::string who, const kit::TcpOptions& tcp,
                         std::uint16_t base_port, std::size_t queue)
    : LineServer(who + " datastreams",
                 [&] {
                   kit::TcpOptions o = tcp;
                   // readers may wait for long
                   o.idle_timeout = o.idle_evict = std::chrono::milliseconds(0);
                   o.io_spin = std::chrono::microseconds(
                       0);  // the I/O thread reads the service port directly only
                   return o;
                 }()),
      io_(io),
      who_(std::move(who)),
      tcp_(tcp),
      limits_(kit::ConnectionLimits::from(tcp)),
      base_port_(base_port),
      queue_(queue) {}

Datastreams::~Datastreams() = default;

// ---- ports (host thread, before the I/O thread runs)

void Datastreams::open(std::shared_ptr<StreamDirectory> hub, std::string transport,
                       RequestManager& manager) {
  if (opened_) return;  // the transport's start() may be called again
  opened_ = true;
  hub_ = std::move(hub);
  transport_ = std::move(transport);
  manager_ = &manager;
  next_port_ = base_port_;
  if (!hub_) return;
  for (const StreamInfo& info : hub_->streams(transport_))
    if (auto port = bind(info)) {
      std::lock_guard lock(ports_mutex_);
      ports_.push_back(std::move(port));
    }
  if (!ports_.empty()) register_services();
}

void Datastreams::sync() {
  if (!hub_) return;
  for (const StreamInfo& info : hub_->streams(transport_)) {
    {
      // a port that still serves this component's stream (one closed when its component
      // went, before a robot of that name was spawned again, does not)
      std::lock_guard lock(ports_mutex_);
      if (std::any_of(
              ports_.begin(), ports_.end(),
              [&](const auto& p) { return p->info.component == info.component && !p->closed; }) ||
          std::any_of(unbound_.begin(), unbound_.end(),
                      [&](const Unbound& u) { return u.component == info.component; }))
        continue;
    }
    auto port = bind(info);
    if (!port) continue;
    listen(*port);
    std::lock_guard lock(ports_mutex_);
    ports_.push_back(std::move(port));
  }
  if (!services_registered_ && !list().empty()) register_services();
}

std::unique_ptr<Datastreams::Port> Datastreams::bind(const StreamInfo& info) {
  auto port = std::make_unique<Port>();
  port->info = info;
  port->who = who_ + ", " + info.component + " stream";
  std::string error;
  std::uint16_t next = next_port_;
  for (int attempt = 0; attempt < k_port_attempts; ++attempt) {
    try {
      port->listener = std::make_unique<kit::TcpListener>(io_, port->who, tcp_.host, next);
      port->number = port->listener->port();
      // MORSE's numbering: the next stream takes the port after this one
      if (base_port_ != 0)
        next_port_ = port->number == 65535 ? 0 : static_cast<std::uint16_t>(port->number + 1);
      log::info(who_, ": ", info.component, " stream (", to_string(info.direction), " ", info.kind,
                ") on ", port->listener->endpoint());
      return port;
    } catch (const std::exception& e) {
      error = e.what();
      if (next == 0 || next == 65535)
        break;  // the system's choice failed, or no port is left above
      ++next;   // MORSE's rule: in use, try the next one
    }
  }
  log::error(who_, ": ", info.component,
             " stream has no port, pymorse and other clients cannot reach it: ", error);
  // get_stream_port says why too: the listener's message, without its who (the answer
  // names the component)
  const std::string prefix = port->who + ": ";
  if (error.starts_with(prefix)) error.erase(0, prefix.size());
  std::lock_guard lock(ports_mutex_);
  unbound_.push_back({info.component, std::move(error)});
  return nullptr;
}

// ---- the services (any thread)

// Under ports_mutex_.
const Datastreams::Port* Datastreams::find(std::string_view component) const {
  // a component removed at run time has no stream any more (the hub forgot it), and a port
  // closed with it serves none (a robot spawned again under its name has a port of its own)
  for (const auto& p : ports_)
    if (p->info.component == component && !p->closed)
      return hub_->find(component, transport_) ? p.get() : nullptr;
  return nullptr;
}

std::vector<std::string> Datastreams::list() const {
  std::lock_guard lock(ports_mutex_);
  std::vector<std::string> names;
  for (const auto& p : ports_)
    if (find(p->info.component) == p.get()) names.push_back(p->info.component);
  return names;
}

int Datastreams::port_of(const std::string& component) const {
  std::lock_guard lock(ports_mutex_);
  if (const Port* p = find(component)) return p->number;
  std::string message =
      "Stream unavailable for component " + component;  // MORSE's words, which pymorse logs
  // then why, for a stream that is there but has no port (pymorse logs the whole message)
  for (const auto& u : unbound_)
    if (u.component == component && hub_->find(component, transport_)) message += ": " + u.reason;
  throw ServiceError(message);
}

json Datastreams::all_ports() const {
  std::lock_guard lock(ports_mutex_);
  json out = json::object();
  for (const auto& p : ports_)
    if (find(p->info.component) == p.get()) out[p->info.component] = p->number;
  return out;
}

void Datastreams::register_services() {
  services_registered_ = true;
  RequestManager& manager = *manager_;
  manager.register_service(
             "simulation", [this] { return list(); }, "list_streams")
      .doc(
          "Components with a datastream port on this socket transport (MORSE's socket "
          "datastreams)");
  manager
      .register_service("simulation", [this](const std::string& name) { return port_of(name); },
                        "get_stream_port", {"name"})
      .doc(
          "The TCP port of a component's datastream: one JSON object per line (what pymorse "
          "connects to)");
  manager.register_service(
             "simulation", [this] { return all_ports(); }, "get_all_stream_ports")
      .doc("{component: port} of every datastream on this socket transport");
}

// ---- connections (I/O thread)

void Datastreams::start() {
  for (const auto& p : ports_) listen(*p);
}

void Datastreams::listen(Port& port) {
  port.listener->start({[this, &port](tcp::socket socket) { accept(port, std::move(socket)); },
                        [this](const tcp::endpoint& peer) { return refusal_reason(peer); },
                        // a stream carries only its samples: a refused client is just closed
                        [](const std::string&) { return std::string(); }});
}

void Datastreams::close_all() {
  for (const auto& p : ports_) {
    p->closed = true;
    p->listener->close();
  }
  LineServer::close_all();  // on_closed() ends each subscription
}

void Datastreams::accept(Port& port, tcp::socket socket) {
  if (port.closed) return;  // its component went; the socket closes here
  kit::LineServer& server = *this;
  auto connection =
      std::make_shared<Connection>(std::move(socket), server, limits_, port, next_connection_++);
  port.connections.push_back(connection);
  add(connection);  // decides whether it must authenticate, starts reading
  if (connection->authenticated() && !connection->closed()) begin(*connection);
}

void Datastreams::begin(Connection& connection) {
  Port& port = connection.port;
  if (port.info.direction == StreamDirection::in) {
    connection.writing = true;
    // MORSE warns too: two writers interleave their commands, the latest wins
    if (++port.writers == 2 && !port.warned_writers) {
      port.warned_writers = true;
      log::warning(port.who, ": ", connection.label(),
                   " is a second client writing commands to this stream: "
                   "the latest command wins (logged once)");
    }
    return;
  }
  connection.subscription = hub_->subscribe(
      port.info.component, transport_,
      SubscriberOptions{queue_,
                        "socket " + connection.label() + " on port " + std::to_string(port.number),
                        [this] { wake(); }});
  if (!connection.subscription) retire(port);  // its component was removed meanwhile
}

void Datastreams::authenticate(Connection& connection, std::string_view line) {
  const std::optional<std::string_view> token = parse_auth_line(line);
  if (token && tcp_.auth.accepts(*token)) {
    connection.set_authenticated();
    log::info(connection.port.who, ": ", connection.label(), " authenticated");
    begin(connection);
    return;
  }
  // one guess per connection, as on the service port; nothing is written on a stream port
  log::warning(
      connection.port.who, ": ", connection.label(),
      token ? " presented a wrong token" : " sent something else than 'auth <token>' first",
      "; connection closed (the transport's \"auth\" option)");
  connection.close("not authenticated");
}

void Datastreams::on_line(kit::LineConnection& c, std::string_view line) {
  auto& connection = static_cast<Connection&>(c);
  if (!connection.authenticated()) [[unlikely]] {
    authenticate(connection, line);
    return;
  }
  // a reader's lines mean nothing: read (so that its socket never fills) and ignored
  if (connection.port.info.direction == StreamDirection::in) publish(connection, line);
}

void Datastreams::publish(Connection& connection, std::string_view line) {
  Port& port = connection.port;
  const auto first = std::find_if(line.begin(), line.end(),
                                  [](char ch) { return ch != ' ' && ch != '\t' && ch != '\r'; });
  if (first == line.end()) return;  // a blank line
  json command = json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (!command.is_object()) {
    // a command all the same, refused: counted with the component's refusals (nothing is
    // written back on a stream port, get_stream_statistics is where a client sees it)
    hub_->note_refused(
        port.info.component, transport_,
        (command.is_discarded() ? "not JSON: " : "not a JSON object: ") + log::quoted_prefix(line));
    if (!connection.warned_malformed) {
      connection.warned_malformed = true;
      log::warning(port.who, ": ", connection.label(), " sent ", log::quoted_prefix(line),
                   command.is_discarded() ? ", which is not JSON" : ", which is not a JSON object",
                   ": ignored; the stream takes one JSON object per line, ",
                   command_example(port.info),
                   " (logged once per connection; simulation get_stream_statistics counts them)");
    }
    return;
  }
  const PublishResult result = hub_->publish(port.info.component, transport_, std::move(command));
  if (result.ok) return;
  if (!hub_->find(port.info.component, transport_)) {
    retire(port);  // its component was removed
    return;
  }
  // refused by the component: the hub counted it and logged the first one of the stream
  log::debug(port.who, ": ", connection.label(), ": command refused: ", result.error);
}

void Datastreams::on_oversized_line(kit::LineConnection& c, std::string_view /*prefix*/,
                                    std::size_t /*bytes*/) {
  auto& connection = static_cast<Connection&>(c);
  if (connection.port.info.direction == StreamDirection::out)
    return;  // a reader's lines mean nothing
  const std::string too_long = "a line longer than " + std::to_string(limits_.max_message_bytes) +
                               " bytes (" + std::string(limits_.message_bytes_key) + ")";
  // counted as a refused command, unless the peer has yet to authenticate (no commands then)
  if (connection.authenticated())
    hub_->note_refused(connection.port.info.component, transport_, too_long);
  if (connection.warned_malformed) return;
  connection.warned_malformed = true;
  log::warning(
      connection.port.who, ": ", connection.label(), " sent ", too_long,
      ": ignored (logged once per connection; simulation get_stream_statistics counts them)");
}

void Datastreams::on_messages_done(kit::Connection& /*connection*/, bool /*read_finished*/) {
  // each command went to the hub as it was read: nothing waits for the end of the read
}

void Datastreams::on_input_ended(kit::LineConnection& /*connection*/) {
  // the client is gone (or will send nothing more): the kit closes the connection once its
  // unsent samples are written
}

void Datastreams::on_closed(kit::Connection& c) {
  auto& connection = static_cast<Connection&>(c);
  Port& port = connection.port;
  if (connection.subscription) hub_->unsubscribe(connection.subscription);
  if (connection.writing) --port.writers;
  std::erase_if(port.connections, [&](const auto& p) { return p.get() == &connection; });
}

void Datastreams::retire(Port& port) {
  if (port.closed) return;
  port.closed = true;
  port.listener->close();
  log::info(port.who, ": the component was removed from the simulation; port ", port.number,
            " and its ", port.connections.size(), " connection(s) closed");
  const auto connections = port.connections;  // each close changes the list
  for (const auto& c : connections) c->close("its component was removed");
}

// ---- samples

void Datastreams::wake() {
  if (woken_.exchange(true, std::memory_order_acq_rel)) return;
  asio::post(io_, [this] { drain(); });
}

void Datastreams::drain() {
  woken_.store(false, std::memory_order_release);
  for (const auto& p : ports_) {
    Port& port = *p;
    if (port.info.direction != StreamDirection::out || port.closed) continue;
    draining_ = port.connections;  // a write may close a connection, which leaves the list
    bool removed = false;
    for (const auto& connection : draining_) {
      // not authenticated yet, or closed by an earlier write of this drain
      if (!connection->subscription || connection->closed()) continue;
      samples_.clear();
      connection->subscription->take(samples_);
      std::uint64_t lost = 0;
      for (const SamplePtr& sample : samples_) {
        const bool queued = connection->queue_droppable_with([&](std::string& out) {
          out += sample->text();
          out += '\n';
        });
        if (!queued) ++lost;
      }
      if (lost > 0) connection->subscription->note_dropped(lost);
      removed = removed || connection->subscription->closed();
    }
    draining_.clear();
    if (removed) retire(port);
  }
  samples_.clear();
  flush_touched();
}

}  // namespace simgate::socket
