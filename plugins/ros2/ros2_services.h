// simgate/ros2 services — the simulation_interfaces services (ros-simulation/simulation_interfaces
// 2.1) and simgate's generic Call service as ROS 2 services, the way rmw_cyclonedds offers a
// service, mapped onto the `simulation` component's services (and, for Call, any service this
// transport serves).
//
// Terms:
//  - service: ROS name ("/step_simulation", under the transport's `service_namespace`), a
//    request reader on "rq/<name>Request" and a reply writer on "rr/<name>Reply", both with
//    USER_DATA "serviceid=<id>;" (the same id: a ROS client sees the service available when it
//    has matched both), reliable, volatile (ROS 2's services profile).
//  - request header: every request and reply begins with the client's id and the request's
//    sequence number (ros2_srvs.idl); a reply carries its request's.
//  - client: a ROS client's request writer and reply reader carry "clientid=<id>;". A reply is
//    written only once its client's reply reader has matched our reply writer (a reply written
//    before is lost: rmw_cyclonedds#191); until then it is parked, written when the match comes,
//    dropped when the client's request writer has gone or after `park_timeout` (logged). A
//    client without a clientid gets its replies at once (as rmw_cyclonedds does).
//  - handling: each request becomes one or more calls of `simulation` services (Caller, run
//    like any request of this transport: access rules, deadlines, the simulation lock); their
//    outcomes become the reply's Result (ros2_sim_interfaces.h: result_of).
//  - other servers: an action's services (ros2_simulate_steps.h) are served by this same
//    machinery: add() makes a service with its own handler, new_reply() and send() answer it.
//
// Threads: everything on the transport's DDS thread; the Caller's continuations run there
// too.
#ifndef SIMGATE_PLUGINS_ROS2_ROS2_SERVICES_H_
#define SIMGATE_PLUGINS_ROS2_ROS2_SERVICES_H_

#include <chrono>
#include <cstdint>
#include <cstring>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include <dds/dds.h>

#include "ros2_sim_interfaces.h"
#include "simgate/core/request_manager.h"

namespace simgate::ros2 {

class Ros2Services {
 public:
  // Waitset tokens: requests to take; a reply writer's matches changed.
  static constexpr dds_attach_t k_token_requests = -4;
  static constexpr dds_attach_t k_token_matched = -5;

  // Runs `call` as a request of the transport and gives its outcome to `done` (on the DDS
  // thread, never from inside the call itself).
  using Caller = std::function<void(Call call, std::function<void(Outcome&&)> done)>;

  // Whom a request's reply goes to: its service, the request header to copy into the reply,
  // the client's request writer (still there?) and its USER_DATA clientid.
  struct ReplyTo {
    std::size_t endpoint = 0;  // the service (add()'s order)
    std::uint64_t client_guid = 0;
    std::int64_t sequence = 0;
    dds_instance_handle_t client_writer = 0;
    std::string client_id;  // the client's USER_DATA clientid, "" when it has none
  };
  // Handles one request (the sample, of the service's request type) on the DDS thread: sends
  // its reply to `to` now or later (send()), or never (the client then waits in vain).
  using Handler = std::function<void(const void* request, const ReplyTo& to)>;

  struct SampleDeleter {
    const dds_topic_descriptor_t* type = nullptr;
    void operator()(void* sample) const;
  };
  using Sample = std::unique_ptr<void, SampleDeleter>;

  struct Settings {
    std::string service_namespace;      // "" or "/ns": the services' names under it
    std::string world_frame = "world";  // frame_id of entity states
    std::chrono::milliseconds park_timeout{10000};
    std::uint32_t max_argument_bytes = 1 << 20;  // Call's arguments, in bytes
    // Whether this transport may call `simulation`.<service> (the features offered)
    std::function<bool(const std::string& service)> may_call;
  };

  // Creates every service's reader and writer on `participant`, attached to `waitset`.
  // `sim_time`: the simulated time of the latest step (entity states' stamps). Throws
  // std::runtime_error when DDS refuses.
  Ros2Services(Settings settings, dds_entity_t participant, dds_entity_t waitset, Caller caller,
               std::function<double()> sim_time);
  ~Ros2Services();
  Ros2Services(const Ros2Services&) = delete;
  Ros2Services& operator=(const Ros2Services&) = delete;

  // The ROS name of `name` ("simulate_steps") under the services' namespace.
  std::string full_name(const std::string& name) const {
    return settings_.service_namespace + "/" + name;
  }

  // One more service, `name` under service_namespace ("simulate_steps/_action/send_goal"),
  // its reader and writer made and attached as every service's; `request` and `reply` are
  // idlc's descriptors (announced by name only). Before the DDS thread starts (the ROS graph
  // is written then). Throws std::runtime_error when DDS refuses.
  void add(const std::string& name, const dds_topic_descriptor_t& request,
           const dds_topic_descriptor_t& reply, Handler handler);

  // ---- DDS thread ----
  // A new reply to `to` (a Response of its service's reply type), zeroed but for the request
  // header; `out` points into it. Every string in it must be set before send().
  template <class Response>
  Sample new_reply(const ReplyTo& to, Response*& out) {
    Sample sample = new_sample(to, sizeof(Response));
    out = static_cast<Response*>(sample.get());
    out->rmw_client_guid = to.client_guid;
    out->rmw_sequence = to.sequence;
    return sample;
  }
  // Writes `reply` now if the client's reader has matched, parks it otherwise.
  void send(const ReplyTo& to, Sample reply);
  // Takes every service's requests and handles them.
  void take_requests();
  // A reply writer's matches changed (k_token_matched): what is known of the clients' readers
  // is read again (which also resets the waitset's trigger: the DDS thread must call this on
  // every such wake, or the waitset wakes it at once, forever), then flush_parked().
  void matches_changed();
  // Writes the parked replies whose client's reader has matched; drops those of gone clients
  // and those past park_timeout.
  void flush_parked();
  // Whether replies are parked (the DDS thread then wakes at least every 10 ms to retry).
  bool has_parked() const { return !parked_.empty(); }
  // Our readers and writers, for the ROS graph.
  void endpoints(std::vector<dds_entity_t>& writers, std::vector<dds_entity_t>& readers) const;
  // The services' ROS names, in the order they were made.
  std::vector<std::string> names() const;

  // Counters (tests, logs).
  std::uint64_t replies_written() const { return written_; }
  std::uint64_t replies_dropped() const { return dropped_; }

 private:
  struct Endpoint;
  struct Parked {
    std::size_t endpoint;
    dds_instance_handle_t client_writer;
    std::string client_id;
    Sample reply;
    std::chrono::steady_clock::time_point deadline;
  };
  using Member = void (Ros2Services::*)(const void* request, const ReplyTo& to);

  // One of the services below.
  void add(const char* name, const dds_topic_descriptor_t& request,
           const dds_topic_descriptor_t& reply, Member handler);
  // A zeroed sample of `size` bytes, of `to`'s reply type.
  Sample new_sample(const ReplyTo& to, std::size_t size) const;
  // Whether the reply writer of `endpoint` has matched a reader with USER_DATA clientid (from
  // what discovery said, read again when the writer's matches changed).
  bool reader_matched(Endpoint& endpoint, const std::string& client_id);
  // The clientid in the USER_DATA of `endpoint`'s matched request writer `writer` ("" when it
  // has none; remembered while the reader's matches do not change).
  const std::string& client_of(Endpoint& endpoint, dds_instance_handle_t writer);
  void write(const Endpoint& endpoint, const Sample& reply);

  // Makes the simulation_interfaces services and simgate/call (ros2_sim_services.cc, with
  // their handlers below; the entities' in ros2_entity_services.cc).
  void add_simulation_services();
  void get_simulator_features(const void* request, const ReplyTo& to);
  void get_simulation_state(const void* request, const ReplyTo& to);
  void set_simulation_state(const void* request, const ReplyTo& to);
  void step_simulation(const void* request, const ReplyTo& to);
  void reset_simulation(const void* request, const ReplyTo& to);
  void get_entities(const void* request, const ReplyTo& to);
  void get_entities_states(const void* request, const ReplyTo& to);
  void get_entity_state(const void* request, const ReplyTo& to);
  void set_entity_state(const void* request, const ReplyTo& to);
  void get_entity_info(const void* request, const ReplyTo& to);
  void get_entity_bounds(const void* request, const ReplyTo& to);
  void spawn_entity(const void* request, const ReplyTo& to);
  void delete_entity(const void* request, const ReplyTo& to);
  void call(const void* request, const ReplyTo& to);

  // Reply helpers: one `simulation` call whose outcome alone makes the Result.
  template <class Response>
  void call_for_result(const ReplyTo& to, Call call, std::string entity_parameter = {});
  // The entities matching `filters` (EntityFilters_), then `done` (on error, the result).
  void list_entities(const void* filters,
                     std::function<void(ServiceResult, std::vector<std::string>)> done);

  const Settings settings_;
  const dds_entity_t participant_;
  const dds_entity_t waitset_;
  Caller caller_;
  std::function<double()> sim_time_;
  std::map<std::string, dds_entity_t> topics_;  // by DDS topic name
  std::vector<std::unique_ptr<Endpoint>> endpoints_;
  std::deque<Parked> parked_;
  std::uint32_t next_service_id_ = 1;
  std::uint64_t written_ = 0, dropped_ = 0;
  std::chrono::steady_clock::time_point drop_logged_at_{};
};

// A sequence of `n` zeroed elements in a sample the transport made (new_reply), owned by it
// (freed with it); returns its buffer.
template <class Seq>
auto* alloc_sequence(Seq& seq, std::size_t n) {
  using Element = std::remove_pointer_t<decltype(seq._buffer)>;
  seq._buffer = nullptr;
  if (n > 0) {
    seq._buffer = static_cast<Element*>(dds_alloc(n * sizeof(Element)));
    std::memset(static_cast<void*>(seq._buffer), 0, n * sizeof(Element));
  }
  seq._length = seq._maximum = static_cast<std::uint32_t>(n);
  seq._release = true;
  return seq._buffer;
}

}  // namespace simgate::ros2

#endif  // SIMGATE_PLUGINS_ROS2_ROS2_SERVICES_H_
