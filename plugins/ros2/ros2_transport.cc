// The ros2 transport: its options, its participant, the DDS thread (waitset loop), /clock,
// the ROS graph (ros_discovery_info) and the scene's frames asked of `simulation`. The
// topics: ros2_topics.cc (with ros2_topic_messages.cc, ros2_topic_commands.cc). Design:
// ros2_transport.h, docs/transports/ros2.md.
#include "ros2_transport.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "cyclone_config.h"
#include "ros2_graph_humble.h"
#include "ros2_msgs.h"
#include "ros2_types.h"
#include "simgate/core/config.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"

namespace simgate::ros2 {

namespace {

// Waitset tokens (Ros2Topics::k_token_commands is -3, Ros2Topics::k_token_matched -6).
constexpr dds_attach_t k_token_guard = -1;

// While service replies are parked, the DDS thread retries them at least this often.
constexpr dds_duration_t k_park_retry = DDS_MSECS(10);

// The longest the DDS thread sleeps: /clock of a paused simulation is written once a second.
constexpr auto k_clock_idle = std::chrono::seconds(1);

Gid gid_of(dds_entity_t entity) {
  dds_guid_t guid;
  Gid gid{};
  if (dds_get_guid(entity, &guid) == DDS_RETCODE_OK)
    std::copy(std::begin(guid.v), std::end(guid.v), gid.begin());
  return gid;
}

// The graph's GIDs of `entities`: their GUIDs, in a Gid of the distribution's size (Humble's 24
// bytes: the GUID, then zeros, as its rmw_cyclonedds fills them).
template <class GidT>
std::vector<GidT> gids_of(const std::vector<dds_entity_t>& entities) {
  std::vector<GidT> out(entities.size());
  for (std::size_t i = 0; i < entities.size(); ++i) {
    const Gid gid = gid_of(entities[i]);
    std::copy(gid.begin(), gid.end(), out[i].data);
  }
  return out;
}

// Writes the one ParticipantEntitiesInfo (Info, with its NodeInfo and GidT: Jazzy's or
// Humble's types) of participant `participant`, whose node `name` in "/" owns `writers` and
// `readers`.
template <class Info, class NodeInfo, class GidT>
dds_return_t write_graph_as(dds_entity_t graph_writer, dds_entity_t participant,
                            const std::string& name, const std::vector<dds_entity_t>& writers,
                            const std::vector<dds_entity_t>& readers) {
  std::vector<GidT> writer_gids = gids_of<GidT>(writers);
  std::vector<GidT> reader_gids = gids_of<GidT>(readers);
  NodeInfo node{};
  // bounded strings (string<256>): the node name is checked to fit by parse()
  std::snprintf(node.node_namespace, sizeof node.node_namespace, "%s", "/");
  std::snprintf(node.node_name, sizeof node.node_name, "%s", name.c_str());
  node.reader_gid_seq._maximum = node.reader_gid_seq._length =
      static_cast<uint32_t>(reader_gids.size());
  node.reader_gid_seq._buffer = reader_gids.data();
  node.writer_gid_seq._maximum = node.writer_gid_seq._length =
      static_cast<uint32_t>(writer_gids.size());
  node.writer_gid_seq._buffer = writer_gids.data();
  Info info{};
  const Gid gid = gid_of(participant);
  std::copy(gid.begin(), gid.end(), info.gid.data);
  info.node_entities_info_seq._maximum = info.node_entities_info_seq._length = 1;
  info.node_entities_info_seq._buffer = &node;
  return dds_write(graph_writer, &info);
}

}  // namespace

Ros2Options Ros2Options::parse(const json& options) {
  ConfigObject config(options.is_null() ? json::object() : options, "");
  Ros2Options out;
  out.domain = static_cast<uint32_t>(config.get_int("domain", 0, 0, 230));
  out.config = config.get_string("config", "");
  out.node_name = config.get_string("node_name", out.node_name);
  if (!is_ros_token(out.node_name) || out.node_name.size() > 256)
    config.fail("node_name",
                "a ROS node name: letters, digits and '_', not starting with a digit, at most "
                "256 characters");
  out.world_frame = config.get_string("world_frame", out.world_frame);
  if (out.world_frame.empty() || out.world_frame.front() == '/')
    config.fail("world_frame", "a tf frame id: not empty, no leading '/'");
  out.clock_hz = config.get_number("clock_hz", out.clock_hz, 0, 10000);
  out.tf = config.get_bool("tf", out.tf);
  out.humble_graph =
      config.get_choice("ros_distro", "jazzy", {"humble", "iron", "jazzy", "kilted", "rolling"}) ==
      "humble";
  if (std::optional<json> robots = config.get_json("robots")) {
    if (!robots->is_array())
      config.fail("robots", "a list of robot names (leave it out for every robot)");
    out.all_robots = false;
    for (std::size_t i = 0; i < robots->size(); ++i) {
      const json& name = (*robots)[i];
      const std::string path = config.path_of("robots") + "[" + std::to_string(i) + "]";
      if (!name.is_string() || name.get<std::string>().empty())
        throw ConfigError(path + ": expected a robot's name, found " + name.dump());
      if (!out.robots.insert(name.get<std::string>()).second)
        throw ConfigError(path + ": robot " + name.dump() + " is named twice");
    }
  }
  out.services = config.get_bool("services", out.services);
  out.service_namespace = config.get_string("service_namespace", "");
  if (!out.service_namespace.empty()) {
    // "/a/b": ROS name tokens after each '/'
    bool valid = out.service_namespace.front() == '/' && out.service_namespace.back() != '/';
    for (std::size_t start = 1; valid && start <= out.service_namespace.size();) {
      const std::size_t end =
          std::min(out.service_namespace.find('/', start), out.service_namespace.size());
      valid = is_ros_token(out.service_namespace.substr(start, end - start));
      start = end + 1;
    }
    if (!valid)
      config.fail("service_namespace",
                  "a ROS namespace: \"/name\" or \"/a/b\" (letters, digits and '_' in each "
                  "part), or \"\" for none");
  }
  out.park_timeout =
      std::chrono::milliseconds(config.get_int("park_timeout_ms", 10000, 10, 600000));
  out.feedback_interval = std::chrono::milliseconds(
      config.get_int("feedback_interval_ms", out.feedback_interval.count(), 0, 60000));
  config.finish();
  return out;
}

void Ros2Transport::validate_options(const json& options) {
  const Ros2Options parsed = Ros2Options::parse(options);
  dds::check_cyclone_config(parsed.domain, parsed.config);
}

Ros2Transport::Ros2Transport(const json& options)
    : RequestManager("ROS 2 topic manager"), options_(Ros2Options::parse(options)) {
  participant_ = std::make_unique<dds::Participant>(
      options_.domain, dds::resolve_config(options_.config),
      "ros2 transport (domain " + std::to_string(options_.domain) + ")");
  const dds_entity_t pp = participant_->handle();
  // USER_DATA as rmw_cyclonedds writes it on its participant
  {
    dds::QosPtr qos(dds_create_qos());
    dds_qset_userdata(qos.get(), k_participant_user_data.data(), k_participant_user_data.size());
    if (dds_return_t rc = dds_set_qos(pp, qos.get()); rc < 0)
      log::debug("ros2 transport: participant USER_DATA not set: ", dds::retcode_text(rc));
  }
  // the ROS graph: reliable, transient-local, keep-last 1 (rmw_cyclonedds' own QoS for it);
  // Humble's types under the same name when asked for
  const char* graph_name = rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc.m_typename;
  const dds_topic_descriptor_t* graph_type =
      options_.humble_graph
          ? name_only(rmw_dds_common_humble_msg_dds__ParticipantEntitiesInfo__desc, graph_name)
          : name_only(rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc);
  dds::QosPtr graph_qos = dds::make_qos(true, 1, 0);
  graph_writer_ = dds::check_created(
      dds_create_writer(
          pp,
          dds::check_created(dds_create_topic(pp, graph_type, k_discovery_topic, nullptr, nullptr),
                             "topic ros_discovery_info"),
          graph_qos.get(), nullptr),
      "writer ros_discovery_info");
  if (options_.clock_hz > 0) {
    // ROS 2's default profile: reliable, volatile, keep-last 10 (a best-effort reader, as
    // rclcpp's clock subscription is, matches it too)
    dds::QosPtr qos = dds::make_qos(false, 10, 0);
    clock_writer_ = dds::check_created(
        dds_create_writer(
            pp,
            dds::check_created(dds_create_topic(pp, name_only(rosgraph_msgs_msg_dds__Clock__desc),
                                                dds_topic_name("/clock").c_str(), nullptr, nullptr),
                               "topic rt/clock"),
            qos.get(), nullptr),
        "writer /clock");
  }
  waitset_ = dds::check_created(dds_create_waitset(pp), "waitset");
  guard_ = dds::check_created(dds_create_guardcondition(pp), "guard condition");
  dds::check_created(dds_waitset_attach(waitset_, guard_, k_token_guard), "waitset attachment");
  if (options_.services) {
    Ros2Services::Settings settings;
    settings.service_namespace = options_.service_namespace;
    settings.world_frame = options_.world_frame;
    settings.park_timeout = options_.park_timeout;
    settings.may_call = [this](const std::string& service) {
      return may_call("simulation", service);
    };
    auto sim_time = [this] { return streams() ? streams()->time() : 0.0; };
    services_ = std::make_unique<Ros2Services>(
        std::move(settings), pp, waitset_,
        [this](Call call, std::function<void(Outcome&&)> done) {
          this->call(std::move(call), std::move(done));
        },
        sim_time);
    // the goals' feedback: the step call's progress reports, as often as this lets them
    set_progress_interval(options_.feedback_interval);
    simulate_steps_ = std::make_unique<Ros2SimulateSteps>(
        Ros2SimulateSteps::Settings{}, *services_, pp,
        [this](Call call, std::function<void(json&&)> progress,
               std::function<void(Outcome&&)> done) {
          return this->call(std::move(call), std::move(done), std::move(progress));
        },
        [this](RequestId id) { cancel(id); }, sim_time);
  }
}

Ros2Transport::~Ros2Transport() { stop(); }

std::vector<std::string> Ros2Transport::endpoints() const {
  return {"ros2:domain=" + std::to_string(options_.domain) + ";node=/" + options_.node_name};
}

void Ros2Transport::start() {
  if (stopping_ || started_.exchange(true)) return;
  if (streams()) {
    Ros2Topics::Settings settings{transport_name(), options_.world_frame, options_.tf,
                                  options_.all_robots, options_.robots};
    topics_ = std::make_unique<Ros2Topics>(streams(), std::move(settings), participant_->handle(),
                                           waitset_, guard_);
  }
  thread_ = std::thread([this] { run(); });
}

void Ros2Transport::stop() {
  if (stopping_.exchange(true)) {
    if (!thread_.joinable()) return;
  }
  if (guard_ > 0) dds_set_guardcondition(guard_, true);
  if (thread_.joinable()) {
    thread_.join();
    // a get_scene_geometry still pending ends here, under the lock (nothing is written)
    deliver_on_any_thread();
    if (gate()) {
      std::lock_guard lock(*gate());
      deliver_handed_over();
    }
  }
  topics_.reset();  // unsubscribes; its entities go with the participant
  simulate_steps_.reset();
  services_.reset();
  continuations_.clear();
  completed_.clear();
  participant_.reset();
}

RequestId Ros2Transport::call(Call call, std::function<void(Outcome&&)> done,
                              std::function<void(json&&)> progress) {
  const RequestId id = new_request_id();
  continuations_.emplace(id, Continuation{std::move(done), std::move(progress)});
  run_or_submit(id, std::move(call));
  run_continuations();
  return id;
}

void Ros2Transport::run_continuations() {
  if (running_continuations_) return;  // the outermost call runs them all
  running_continuations_ = true;
  while (!completed_.empty()) {
    auto [id, event] = std::move(completed_.front());
    completed_.pop_front();
    auto it = continuations_.find(id);
    if (it == continuations_.end()) continue;
    try {
      if (json* progress = std::get_if<json>(&event)) {
        // the call goes on: its continuations stay
        if (it->second.progress) it->second.progress(std::move(*progress));
        continue;
      }
      auto done = std::move(it->second.done);
      continuations_.erase(it);
      done(std::get<Outcome>(std::move(event)));
    } catch (const std::exception& e) {
      log::error("ros2 transport: ", e.what());
    }
  }
  running_continuations_ = false;
}

void Ros2Transport::on_service_completion(RequestId id, Outcome&& outcome) {
  const auto geometry = geometry_calls_.find(id);
  if (geometry == geometry_calls_.end()) {
    // a service's call: its continuation runs once the lock is released (run_continuations)
    if (!stopping_ && continuations_.count(id))
      completed_.emplace_back(id, Event(std::in_place_type<Outcome>, std::move(outcome)));
    return;
  }
  const std::string component = std::move(geometry->second);
  geometry_calls_.erase(geometry);
  if (stopping_ || !topics_) return;
  if (outcome.status == Status::success && outcome.value) {
    try {
      topics_->set_geometry(component, *outcome.value);
      return;
    } catch (const std::exception& e) {
      outcome.message = std::string("its answer is malformed: ") + e.what();
    }
  }
  topics_->refuse_geometry(component);
  if (!geometry_failure_logged_)
    log::error("ros2 transport: /tf needs the model's frames from `", component,
               " get_scene_geometry` through this transport (map simulation's services to it: "
               "\"services\": {\"simulation\": [..., \"",
               transport_name(), "\"]}): ", outcome.message, " (logged once)");
  geometry_failure_logged_ = true;
}

void Ros2Transport::on_service_progress(RequestId id, json&& value) {
  // run by run_continuations, after the outcomes and reports that came before it
  if (!stopping_ && continuations_.count(id))
    completed_.emplace_back(id, Event(std::in_place_type<json>, std::move(value)));
}

void Ros2Transport::on_services_changed() {
  streams_changed_ = true;
  if (started_ && !stopping_ && guard_ > 0) dds_set_guardcondition(guard_, true);
}

void Ros2Transport::ask_geometry(const std::string& component) {
  for (const auto& [id, asked] : geometry_calls_)
    if (asked == component) return;  // under way
  const RequestId id = new_request_id();
  geometry_calls_.emplace(id, component);
  // "w1/simulation" is world 1's simulation component
  run_or_submit(id, Call{component, "get_scene_geometry", json{{"include_meshes", false}}});
}

void Ros2Transport::sync_topics() {
  streams_changed_ = false;
  if (topics_ && topics_->sync()) write_graph();
}

void Ros2Transport::write_clock(bool force) {
  if (clock_writer_ == 0 || !streams()) return;
  const double now = streams()->time();
  const auto wall = std::chrono::steady_clock::now();
  if (!force && now == clock_written_ && wall - clock_written_at_ < k_clock_idle) return;
  rosgraph_msgs_msg_dds__Clock_ message{};
  const RosTime t = to_ros_time(now);
  message.clock.sec = t.sec;  // by name: not by the IDL's order
  message.clock.nanosec = t.nanosec;
  if (dds_return_t rc = dds_write(clock_writer_, &message); rc < 0) {
    log::debug("ros2 transport: /clock not written: ", dds::retcode_text(rc));
    return;
  }
  clock_written_ = now;
  clock_written_at_ = wall;
}

void Ros2Transport::write_graph() {
  std::vector<dds_entity_t> writers, readers;
  if (clock_writer_ > 0) writers.push_back(clock_writer_);
  if (topics_) topics_->endpoints(writers, readers);
  if (services_) services_->endpoints(writers, readers);
  if (simulate_steps_) simulate_steps_->endpoints(writers, readers);
  const dds_entity_t pp = participant_->handle();
  const dds_return_t rc =
      options_.humble_graph
          ? write_graph_as<rmw_dds_common_humble_msg_dds__ParticipantEntitiesInfo_,
                           rmw_dds_common_humble_msg_dds__NodeEntitiesInfo_,
                           rmw_dds_common_humble_msg_dds__Gid_>(
                graph_writer_, pp, options_.node_name, writers, readers)
          : write_graph_as<rmw_dds_common_msg_dds__ParticipantEntitiesInfo_,
                           rmw_dds_common_msg_dds__NodeEntitiesInfo_, rmw_dds_common_msg_dds__Gid_>(
                graph_writer_, pp, options_.node_name, writers, readers);
  if (rc < 0) log::error("ros2 transport: ros_discovery_info not written: ", dds::retcode_text(rc));
}

void Ros2Transport::run() {
  // outcomes produced on other threads (get_scene_geometry run by the simulation thread):
  // the guard wakes this thread, which delivers them
  deliver_on_this_thread([this] { dds_set_guardcondition(guard_, true); });
  const auto period = options_.clock_hz > 0
                          ? std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                std::chrono::duration<double>(1.0 / options_.clock_hz))
                          : std::chrono::steady_clock::duration(k_clock_idle);
  auto next_clock = std::chrono::steady_clock::now();
  try {
    streams_changed_ = false;
    if (topics_) topics_->sync();
    write_graph();  // the node, also with no topic yet
  } catch (const std::exception& e) {
    log::error("ros2 transport: ", e.what());
  }
  constexpr dds_return_t k_slots = 8;
  dds_attach_t triggered[k_slots];
  while (!stopping_) {
    const auto left = next_clock - std::chrono::steady_clock::now();
    const dds_duration_t timeout = std::clamp<dds_duration_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(left).count(), 0,
        services_ && services_->has_parked() ? k_park_retry : DDS_SECS(1));
    const dds_return_t n = dds_waitset_wait(waitset_, triggered, k_slots, timeout);
    if (n < 0) {
      log::error("ros2 transport: waitset failed: ", dds::retcode_text(n));
      break;
    }
    bool guard = n > k_slots, commands = n > k_slots, requests = n > k_slots, matched = n > k_slots,
         readers = n > k_slots;
    for (dds_return_t i = 0; i < std::min(n, k_slots); ++i) {
      guard |= triggered[i] == k_token_guard;
      commands |= triggered[i] == Ros2Topics::k_token_commands;
      requests |= triggered[i] == Ros2Services::k_token_requests;
      matched |= triggered[i] == Ros2Services::k_token_matched;
      readers |= triggered[i] == Ros2Topics::k_token_matched;
    }
    try {
      if (guard) {
        bool ignored;
        dds_take_guardcondition(guard_, &ignored);
        deliver_handed_over();
        run_continuations();
        if (streams_changed_) sync_topics();
        if (topics_) topics_->write_samples();
      }
      if (services_) {
        // a reader matching or leaving wakes the thread (and must be taken, or the waitset
        // wakes it again at once): parked replies may go
        if (matched) services_->matches_changed();
        if (requests) services_->take_requests();
        // a reply waits for its client's reader: retried on every wake, and at least every
        // k_park_retry
        if (services_->has_parked()) services_->flush_parked();
      }
      if (simulate_steps_) simulate_steps_->expire();
      if (topics_)
        for (const std::string& component : topics_->take_geometry_wanted())
          ask_geometry(component);
      if (topics_ && commands) topics_->take_commands();
      // a camera's reader came or went: rendered for us only while read
      if (topics_ && readers) topics_->matches_changed();
      if (options_.clock_hz > 0 && std::chrono::steady_clock::now() >= next_clock) {
        write_clock(false);
        next_clock += period;
        // behind by more than a period (a long stall): start again from now
        if (next_clock < std::chrono::steady_clock::now())
          next_clock = std::chrono::steady_clock::now() + period;
      } else if (options_.clock_hz <= 0) {
        next_clock = std::chrono::steady_clock::now() + period;
      }
    } catch (const std::exception& e) {
      // keep serving everything else
      log::error("ros2 transport: ", e.what());
    }
  }
}

}  // namespace simgate::ros2

SIMGATE_TRANSPORT_PLUGIN(ros2, simgate::ros2::Ros2Transport, "0.1.0", "domain", "config",
                         "node_name", "world_frame", "clock_hz", "tf", "robots", "ros_distro",
                         "services", "service_namespace", "park_timeout_ms", "feedback_interval_ms")
