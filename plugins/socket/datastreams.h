// datastreams.h — MORSE's socket datastreams on the socket transport (issue #21).
//
// MORSE gives every component streamed over its socket middleware a TCP port of its own
// (from 60000 up), on which a sensor's samples go out as one JSON object per line and an
// actuator's commands come in the same way; `simulation get_stream_port ["robot.pose"]`
// says which port (pymorse asks it for every component whose `details` list
// stream_interfaces). Datastreams does that for the streams the configuration gives this
// socket transport (StreamHub::streams), over the core's StreamHub:
//
//   - Ports: one listener per stream on the transport's host, opened when the transport
//     starts (the streams are known then): from `stream_port` up, a port in use skipped for
//     the next one, as MORSE does; `stream_port` 0 gives each stream a free port of the
//     system's choosing. A stream whose port cannot be opened is logged and left out
//     (get_stream_port answers why). A stream added later (a robot spawned at run time:
//     sync(), when the transport's services change) gets a port the same way, numbered
//     after the last.
//   - Output stream (sensor): each connection subscribes (StreamHub::subscribe, keeping the
//     latest `stream_queue` samples) and gets every sample as `<json>\n`, in order. A client
//     that does not read loses samples, never slows anyone: past
//     kit::Connection::k_droppable_unsent_bytes unsent, samples are dropped and counted
//     (StreamSubscription::note_dropped). What such a client sends is read and ignored.
//   - Input stream (actuator): each line is one JSON object, a command published to the
//     hub (applied at once when the simulation lock is free, else the latest wins at the
//     next turn). Nothing is ever written back (MORSE's protocol has no reply there): a line
//     that is not a JSON object, or is too long, is counted as a refused command
//     (StreamHub::note_refused) and logged once per connection; a command the component
//     refuses is counted and logged by the hub.
//   - Services (only when at least one stream has a port, as MORSE registers them only
//     then): `simulation list_streams`, `get_stream_port [name]` (FAILED "Stream
//     unavailable for component <name>", MORSE's text, followed by ": <why>" for a stream
//     whose port could not be bound), `get_all_stream_ports`, in the socket manager's own
//     table. A stream without a port is in neither list.
//   - A component removed at run time: its port and connections are closed (one spawned
//     again under its name later gets a port anew).
//
// Connections are the kit's line connections (framing, limits, coalesced writes), served
// by a LineServer of their own with the transport's limits, except that a stream
// connection is never closed for being idle (a reader of a paused simulation hears nothing
// for as long as it stays paused) and its I/O thread never reads it directly. A peer the
// transport's "auth" option concerns presents `auth <token>` as its first line (nothing is
// answered; a wrong token closes the connection): until then it gets no sample and its
// lines are not commands.
//
// The stream ports are not in the transport's endpoints(): those are the service port a
// client connects to (and tests and the banner read the first one); clients find a stream's
// port through the services, and the log names each at start.
//
// Life cycle: open() (the host thread, in SocketRequestManager::start(), before the I/O
// thread runs), start(), sync() and close_all() on the I/O thread.
// Threads: the transport's I/O thread, except open() (before it runs), the services
// (whichever thread holds the simulation lock: they read the ports under ports_mutex_, and
// the hub) and wake() (the thread holding the simulation lock: it posts).
#ifndef SIMGATE_PLUGINS_SOCKET_DATASTREAMS_H_
#define SIMGATE_PLUGINS_SOCKET_DATASTREAMS_H_

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "simgate/core/request_manager.h"
#include "simgate/core/streams.h"
#include "simgate/kit/line_connection.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::socket {

class Datastreams : private kit::LineServer {
 public:
  // `io`: the transport's; `who` names it in logs ("Socket service manager"); `tcp`: its
  // options (host, limits, auth); `base_port`: "stream_port"; `queue`: "stream_queue".
  Datastreams(boost::asio::io_context& io, std::string who, const kit::TcpOptions& tcp,
              std::uint16_t base_port, std::size_t queue);
  ~Datastreams() override;
  Datastreams(const Datastreams&) = delete;
  Datastreams& operator=(const Datastreams&) = delete;

  // Opens a port for every stream `transport` carries in `hub`, logging each, and, when one
  // has a port, registers `simulation list_streams`, `get_stream_port` and
  // `get_all_stream_ports` in `manager`'s table (MORSE registers them only then). A second
  // call does nothing.
  void open(std::shared_ptr<StreamDirectory> hub, std::string transport, RequestManager& manager);
  // Accepts on every port (the I/O thread).
  void start();
  // Opens and accepts on a port for each stream the hub lists now that has none (added since:
  // a robot spawned at run time), registering the services with the first (the I/O thread).
  void sync();
  // Closes every port and connection, ending their subscriptions (the I/O thread, when the
  // transport stops). Idempotent.
  void close_all();

  // What the services answer (any thread): the components with a stream port here, in the
  // hub's order; the port of `component`'s stream (throws ServiceError, MORSE's message,
  // when it has none); {component: port}.
  std::vector<std::string> list() const;
  int port_of(const std::string& component) const;
  json all_ports() const;

 private:
  class Connection;
  // One stream and its port. Fixed by open(), except what the I/O thread keeps.
  struct Port {
    StreamInfo info;                             // the stream
    std::string who;                             // "Socket service manager, robot.pose stream"
    std::unique_ptr<kit::TcpListener> listener;  // bound by open()
    std::uint16_t number = 0;                    // the bound port
    // I/O thread:
    std::vector<std::shared_ptr<Connection>> connections;  // open ones
    std::size_t writers = 0;                               // input stream: connections writing now
    bool warned_writers = false;                           // a second writer was warned about
    // its component was removed, or close_all() (read by the services)
    std::atomic<bool> closed{false};
  };

  // Binds a port for `info`, from next_port_ (0: any) up while in use, and moves next_port_
  // after it (MORSE's numbering); logs it. Null (logged, kept in unbound_) when none could be
  // bound.
  std::unique_ptr<Port> bind(const StreamInfo& info);
  // Accepts on `port` (the I/O thread).
  void listen(Port& port);
  void register_services();
  const Port* find(std::string_view component) const;
  void accept(Port& port, boost::asio::ip::tcp::socket socket);
  // The connection may have the stream: subscribes a reader, counts a writer.
  void begin(Connection& connection);
  // A peer that must authenticate: its first line is `auth <token>`, or it is closed.
  void authenticate(Connection& connection, std::string_view line);
  // An input stream's line: the command it holds, to the hub.
  void publish(Connection& connection, std::string_view line);
  // The component of `port` was removed: its port and connections close.
  void retire(Port& port);
  // A subscription has samples (the thread that holds the simulation lock): one post per burst.
  void wake();
  // Writes every reader's samples; retires the ports whose component was removed.
  void drain();

  // kit::LineServer (I/O thread)
  void on_line(kit::LineConnection& connection, std::string_view line) override;
  void on_oversized_line(kit::LineConnection& connection, std::string_view prefix,
                         std::size_t bytes) override;
  void on_messages_done(kit::Connection& connection, bool read_finished) override;
  void on_input_ended(kit::LineConnection& connection) override;
  void on_closed(kit::Connection& connection) override;

  boost::asio::io_context& io_;           // the transport's
  std::string who_;                       // for logs
  kit::TcpOptions tcp_;                   // the transport's options (host, auth)
  kit::ConnectionLimits limits_;          // per connection
  std::uint16_t base_port_;               // "stream_port"
  std::size_t queue_;                     // "stream_queue"
  std::shared_ptr<StreamDirectory> hub_;  // from open()
  std::string transport_;                 // the configuration's name of this transport
  bool opened_ = false;                   // open() ran
  RequestManager* manager_ = nullptr;     // whose table gets the services (from open())
  bool services_registered_ = false;      // they are in it
  std::uint16_t next_port_ = 0;           // the next stream's port (0: the system's choice)
  // ports_ and unbound_: added to by the I/O thread (and open()), read by the services
  mutable std::mutex ports_mutex_;
  std::vector<std::unique_ptr<Port>> ports_;  // in the order their streams were added
  // A stream whose port could not be bound, and why (get_stream_port says it).
  struct Unbound {
    std::string component;
    // "cannot listen on 127.0.0.1:60000: bind failed: Address already in use ..."
    std::string reason;
  };
  std::vector<Unbound> unbound_;
  std::uint64_t next_connection_ = 1;  // numbers connections in logs (I/O thread)
  std::vector<SamplePtr> samples_;     // drain's scratch (I/O thread)
  std::vector<std::shared_ptr<Connection>>
      draining_;                    // drain's copy of a port's readers (I/O thread)
  std::atomic<bool> woken_{false};  // a drain is posted
};

}  // namespace simgate::socket

#endif  // SIMGATE_PLUGINS_SOCKET_DATASTREAMS_H_
