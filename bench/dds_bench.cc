// dds_bench.cc — DDS round trips: simgate's DDS transport against a raw Cyclone ping-pong.
//
// Modes (--mode):
//   pong     the raw server: reads simgate_Request samples and answers each at once with a
//            simgate_Reply (result "3"), on its own waitset thread. No simgate core at all.
//   ping     the raw client: writes a Request, waits for its Reply, --count times.
//   client   simgate's DdsClient calling `test_component add [1, 2]` on a transport host
//            (simgate_bench_host --transport dds) --count times.
//   step     simgate's DdsClient calling `simulation step {"n": 1}` on a gateway started paused
//            (simgate run), --count times: one physics step per round trip.
//   ros2-step   a ROS 2 client as rmw_cyclonedds makes one (raw Cyclone, the types of
//            protocols/ros2/ros2_srvs.idl: the request header, USER_DATA clientid) calling the
//            ros2 transport's /step_simulation {steps: 1} on the same gateway, --count times:
//            issue #41's StepSimulation round trip against `step` (simgate's own DDS request).
//   ros2-tf  a ROS 2 reader of /tf (tf2_msgs/TFMessage) for --duration seconds: messages and
//            transforms per second.
//   camera   simgate's DdsClient calling `<--camera> get_image` on a gateway (simgate run,
//            its camera served by DDS) --count times, one after the other, with raw_images
//            (--raw) or not: frames/s, and the bytes of the reply's text. The render thread's
//            work per frame is what the rate shows (the camera renders each get_image).
// ping and pong use simgate's own wire types (protocols/dds/simgate_dds.idl), the same topics,
// the same payload ("test_component", "add", "[1,2]") and the same QoS as the transport
// (RELIABLE, KEEP_ALL, VOLATILE, partition), so the ratio is what simgate adds on top of
// Cyclone: the request table, the core's process() (run on the transport's DDS thread when
// the simulation lock is free, as in the host here), JSON, the reply filter, and the
// client's call table (DdsClient's caller takes its own reply, as ping does).
// Cyclone is restricted to loopback with multicast off (the compiled-in loopback XML).
//
// Usage: simgate_bench_dds --mode pong|ping|client|camera [--domain D] [--partition P]
//        [--count N] [--warmup W] [--timeout S] [--camera C] [--raw]
// pong prints {"ready": true} once its entities exist and runs until SIGTERM/SIGINT or
// --timeout; ping and client print latency percentiles (µs) as JSON.
#include <atomic>
#include <csignal>
#include <cstring>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bench_util.h"
#include "dds_support.h"
#include "simgate/client/dds_client.h"
#ifdef SIMGATE_BENCH_ROS2
#include "ros2_msgs.h"
#include "ros2_sim_interfaces.h"
#include "ros2_srvs.h"
#include "ros2_types.h"
#endif

namespace {

using simgate::bench::Clock;
using simgate::bench::json;

std::atomic<bool> g_stop{false};  // set by the signal handler
extern "C" void on_signal(int) { g_stop.store(true); }

dds_entity_t check(dds_entity_t e, const char* what) {
  if (e < 0)
    throw std::runtime_error(std::string("raw DDS ") + what + ": " + simgate::dds::retcode_text(e));
  return e;
}

// Participant, partitioned publisher/subscriber and the two topics, like the transport.
struct RawEndpoints {
  simgate::dds::Participant participant;
  dds_entity_t publisher = 0, subscriber = 0, request_topic = 0, reply_topic = 0;

  RawEndpoints(std::uint32_t domain, const std::string& partition)
      : participant(domain, simgate::dds::k_loopback_xml, "raw DDS ping-pong") {
    dds_entity_t pp = participant.handle();
    simgate::dds::QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), partition.c_str());
    publisher = check(dds_create_publisher(pp, partition_qos.get(), nullptr), "publisher");
    subscriber = check(dds_create_subscriber(pp, partition_qos.get(), nullptr), "subscriber");
    request_topic = check(dds_create_topic(pp, &simgate_Request_desc, simgate::dds::k_request_topic,
                                           nullptr, nullptr),
                          "request topic");
    reply_topic = check(
        dds_create_topic(pp, &simgate_Reply_desc, simgate::dds::k_reply_topic, nullptr, nullptr),
        "reply topic");
  }
  // reliable, keep-all, volatile: the transport's request and reply QoS
  static simgate::dds::QosPtr qos() { return simgate::dds::make_qos(false, 0, DDS_SECS(1)); }
};

// Waits until `entity` reports `status` (a match) or the deadline passes.
void wait_matched(dds_entity_t entity, bool writer, Clock::time_point deadline) {
  for (;;) {
    std::int32_t count = 0;
    if (writer) {
      dds_publication_matched_status_t s;
      dds_get_publication_matched_status(entity, &s);
      count = static_cast<std::int32_t>(s.current_count);
    } else {
      dds_subscription_matched_status_t s;
      dds_get_subscription_matched_status(entity, &s);
      count = static_cast<std::int32_t>(s.current_count);
    }
    if (count > 0) return;
    if (Clock::now() > deadline)
      throw std::runtime_error("raw DDS: no peer matched before the timeout");
    dds_sleepfor(DDS_MSECS(5));
  }
}

// Raw round trips on `writer` / `reader` (a read condition of `reader` attached to `waitset`):
// `warmup + count` times, send(i) writes request i, then replies are taken until answers(reply,
// i) says one is request i's (it counts a wrong one in `errors` itself). The last `count`
// round trips' durations, in ns.
template <class Reply, class Send, class Answers>
std::vector<std::int64_t> raw_round_trips(dds_entity_t reader, dds_entity_t waitset,
                                          std::size_t count, std::size_t warmup,
                                          Clock::time_point deadline, const char* what, Send send,
                                          Answers answers) {
  std::vector<std::int64_t> samples;
  void* got[1] = {};
  dds_sample_info_t info;
  for (std::size_t i = 0; i < warmup + count; ++i) {
    auto t0 = Clock::now();
    send(i);
    bool answered = false;
    while (!answered) {
      if (Clock::now() > deadline) throw std::runtime_error(std::string(what) + ": timed out");
      dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(100));
      got[0] = nullptr;
      dds_return_t n = dds_take(reader, got, &info, 1, 1);
      if (n <= 0) continue;
      if (info.valid_data) answered = answers(*static_cast<const Reply*>(got[0]), i);
      dds_return_loan(reader, got, n);
    }
    if (i >= warmup) samples.push_back(simgate::bench::ns_between(t0, Clock::now()));
  }
  return samples;
}

int run_pong(std::uint32_t domain, const std::string& partition, double timeout_s) {
  RawEndpoints ep(domain, partition);
  auto qos = RawEndpoints::qos();
  dds_entity_t reader =
      check(dds_create_reader(ep.subscriber, ep.request_topic, qos.get(), nullptr), "reader");
  dds_entity_t writer =
      check(dds_create_writer(ep.publisher, ep.reply_topic, qos.get(), nullptr), "writer");
  dds_entity_t waitset = check(dds_create_waitset(ep.participant.handle()), "waitset");
  dds_entity_t cond = check(dds_create_readcondition(reader, DDS_ANY_STATE), "read condition");
  check(dds_waitset_attach(waitset, cond, 0), "waitset attach");
  std::cout << json{{"ready", true}}.dump() << std::endl;

  // answer every request at once, until a signal or the time limit
  auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(timeout_s));
  void* samples[16] = {};
  dds_sample_info_t infos[16];
  static char k_result[] = "3", k_empty[] = "";
  while (!g_stop.load() && Clock::now() < deadline) {
    dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(50));
    for (;;) {
      dds_return_t n = dds_take(reader, samples, infos, 16, 16);
      if (n <= 0) break;
      for (int i = 0; i < n; ++i) {
        if (!infos[i].valid_data) continue;
        auto* req = static_cast<simgate_Request*>(samples[i]);
        simgate_Reply reply{};
        std::memcpy(reply.client, req->id.client, sizeof reply.client);
        reply.seq = req->id.seq;
        reply.status = simgate_ST_SUCCESS;
        reply.failure = simgate_FL_NONE;
        reply.last = true;
        reply.result = k_result;
        reply.message = k_empty;
        reply.data = k_empty;
        dds_write(writer, &reply);
      }
      dds_return_loan(reader, samples, n);
    }
  }
  return 0;
}

json run_ping(std::uint32_t domain, const std::string& partition, std::size_t count,
              std::size_t warmup, double timeout_s) {
  RawEndpoints ep(domain, partition);
  auto qos = RawEndpoints::qos();
  dds_entity_t writer =
      check(dds_create_writer(ep.publisher, ep.request_topic, qos.get(), nullptr), "writer");
  dds_entity_t reader =
      check(dds_create_reader(ep.subscriber, ep.reply_topic, qos.get(), nullptr), "reader");
  dds_entity_t waitset = check(dds_create_waitset(ep.participant.handle()), "waitset");
  dds_entity_t cond = check(dds_create_readcondition(reader, DDS_ANY_STATE), "read condition");
  check(dds_waitset_attach(waitset, cond, 0), "waitset attach");
  auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(timeout_s));
  wait_matched(writer, true, deadline);
  wait_matched(reader, false, deadline);

  static char k_component[] = "test_component", k_service[] = "add", k_params[] = "[1,2]";
  simgate_Request req{};
  for (int i = 0; i < 16; ++i) req.id.client[i] = static_cast<std::uint8_t>(i + 1);
  req.op = simgate_OP_CALL;
  req.component = k_component;
  req.service = k_service;
  req.params = k_params;
  std::size_t errors = 0;
  std::vector<std::int64_t> samples = raw_round_trips<simgate_Reply>(
      reader, waitset, count, warmup, deadline, "raw DDS ping",
      [&](std::size_t i) {
        req.id.seq = i + 1;
        if (dds_write(writer, &req) < 0) ++errors;
      },
      [&](const simgate_Reply& reply, std::size_t) {
        if (reply.seq != req.id.seq) return false;
        if (std::strcmp(reply.result, "3") != 0) ++errors;
        return true;
      });
  json out = simgate::bench::summarize_us(std::move(samples));
  out["errors"] = errors;
  return out;
}

// A DdsClient of the server in `partition`, once it has found it (within `timeout_s`).
std::unique_ptr<simgate::client::DdsClient> connect(std::uint32_t domain,
                                                    const std::string& partition, double timeout_s,
                                                    bool raw_images = false) {
  simgate::client::DdsClientOptions options;
  options.domain = domain;
  options.partition = partition;
  options.raw_images = raw_images;
  options.discovery_timeout = std::chrono::milliseconds(static_cast<long long>(timeout_s * 1000));
  auto client = std::make_unique<simgate::client::DdsClient>(options);
  if (!client->wait_for_server(options.discovery_timeout))
    throw std::runtime_error("simgate DDS client: no server in partition '" + partition + "'");
  return client;
}

// DdsClient round trips of `component`.`service`(`params`), one after the other; `ok` says
// whether an outcome is the expected one (a wrong one is counted in "errors").
template <class Ok>
json run_calls(std::uint32_t domain, const std::string& partition, std::size_t count,
               std::size_t warmup, double timeout_s, const char* component, const char* service,
               const simgate::json& params, Ok ok) {
  auto connection = connect(domain, partition, timeout_s);
  simgate::client::DdsClient& client = *connection;
  std::vector<std::int64_t> samples;
  std::size_t errors = 0;
  std::string first;
  for (std::size_t i = 0; i < warmup + count; ++i) {
    auto t0 = Clock::now();
    auto outcome = client.call(component, service, params, std::chrono::seconds(10));
    auto t1 = Clock::now();
    if (!ok(outcome)) ++errors;
    if (i == 0)
      first =
          outcome.value ? outcome.value->dump() : std::string(simgate::to_string(outcome.status));
    if (i >= warmup) samples.push_back(simgate::bench::ns_between(t0, t1));
  }
  json out = simgate::bench::summarize_us(std::move(samples));
  out["errors"] = errors;
  out["first_reply"] = first;
  return out;
}

// `test_component add [1, 2]` on a transport host: 3 each time.
json run_client(std::uint32_t domain, const std::string& partition, std::size_t count,
                std::size_t warmup, double timeout_s) {
  return run_calls(domain, partition, count, warmup, timeout_s, "test_component", "add",
                   simgate::json::array({1, 2}), [](const simgate::Outcome& outcome) {
                     return outcome.status == simgate::Status::success && outcome.value &&
                            *outcome.value == 3;
                   });
}

// `simulation step {"n": 1}` on a gateway started paused: one physics step per round trip.
json run_step(std::uint32_t domain, const std::string& partition, std::size_t count,
              std::size_t warmup, double timeout_s) {
  return run_calls(
      domain, partition, count, warmup, timeout_s, "simulation", "step", simgate::json{{"n", 1}},
      [](const simgate::Outcome& outcome) { return outcome.status == simgate::Status::success; });
}

#ifdef SIMGATE_BENCH_ROS2
// A ROS 2 participant on `domain` (Cyclone on loopback), its topics announced by name only as
// rmw_cyclonedds announces them.
struct Ros2Endpoints {
  simgate::dds::Participant participant;
  std::map<std::string, dds_entity_t> topics;
  explicit Ros2Endpoints(std::uint32_t domain)
      : participant(domain, simgate::dds::k_loopback_xml, "ROS 2 bench client") {}
  dds_entity_t topic(const std::string& name, const dds_topic_descriptor_t& type) {
    return simgate::dds::cached_topic(topics, participant.handle(), name,
                                      simgate::ros2::name_only(type));
  }
};

json run_ros2_step(std::uint32_t domain, std::size_t count, std::size_t warmup, double timeout_s) {
  Ros2Endpoints ep(domain);
  const dds_entity_t pp = ep.participant.handle();
  // rmw_cyclonedds' client: both endpoints with its clientid, ROS 2's services profile
  const std::string user_data = "clientid=bench.1;";
  simgate::dds::QosPtr qos = simgate::dds::make_qos(false, 10, DDS_SECS(1));
  dds_qset_userdata(qos.get(), user_data.data(), user_data.size());
  dds_entity_t writer =
      check(dds_create_writer(pp,
                              ep.topic(simgate::ros2::service_request_topic("/step_simulation"),
                                       simulation_interfaces_srv_dds__StepSimulation_Request__desc),
                              qos.get(), nullptr),
            "writer");
  dds_entity_t reader = check(
      dds_create_reader(pp,
                        ep.topic(simgate::ros2::service_reply_topic("/step_simulation"),
                                 simulation_interfaces_srv_dds__StepSimulation_Response__desc),
                        qos.get(), nullptr),
      "reader");
  dds_entity_t waitset = check(dds_create_waitset(pp), "waitset");
  dds_entity_t cond = check(dds_create_readcondition(reader, DDS_ANY_STATE), "read condition");
  check(dds_waitset_attach(waitset, cond, 0), "waitset attach");
  auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(timeout_s));
  wait_matched(writer, true, deadline);
  wait_matched(reader, false, deadline);
  simulation_interfaces_srv_dds__StepSimulation_Request_ request{};
  request.rmw_client_guid = 0x0123456789abcdefULL;
  request.steps = 1;
  using Reply = simulation_interfaces_srv_dds__StepSimulation_Response_;
  std::size_t errors = 0;
  std::vector<std::int64_t> samples = raw_round_trips<Reply>(
      reader, waitset, count, warmup, deadline, "ROS 2 StepSimulation",
      [&](std::size_t i) {
        request.rmw_sequence = static_cast<std::int64_t>(i + 1);
        if (dds_write(writer, &request) < 0) ++errors;
      },
      [&](const Reply& reply, std::size_t) {
        if (reply.rmw_client_guid != request.rmw_client_guid ||
            reply.rmw_sequence != request.rmw_sequence)
          return false;
        if (reply.result.result != 1) ++errors;
        return true;
      });
  json out = simgate::bench::summarize_us(std::move(samples));
  out["errors"] = errors;
  return out;
}

json run_ros2_tf(std::uint32_t domain, double duration_s, double timeout_s) {
  Ros2Endpoints ep(domain);
  const dds_entity_t pp = ep.participant.handle();
  // tf2's listener: reliable, volatile, keep-last 100
  simgate::dds::QosPtr qos = simgate::dds::make_qos(false, 100, DDS_SECS(1));
  dds_entity_t reader =
      check(dds_create_reader(pp, ep.topic("rt/tf", tf2_msgs_msg_dds__TFMessage__desc), qos.get(),
                              nullptr),
            "reader");
  dds_entity_t waitset = check(dds_create_waitset(pp), "waitset");
  dds_entity_t cond = check(dds_create_readcondition(reader, DDS_ANY_STATE), "read condition");
  check(dds_waitset_attach(waitset, cond, 0), "waitset attach");
  wait_matched(reader, false,
               Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                  std::chrono::duration<double>(timeout_s)));
  void* got[16] = {};
  dds_sample_info_t infos[16];
  std::size_t messages = 0, transforms = 0;
  const auto started = Clock::now();
  const auto end = started + std::chrono::duration_cast<Clock::duration>(
                                 std::chrono::duration<double>(duration_s));
  while (Clock::now() < end) {
    dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(50));
    for (;;) {
      std::fill(std::begin(got), std::end(got), nullptr);
      dds_return_t n = dds_take(reader, got, infos, 16, 16);
      if (n <= 0) break;
      for (dds_return_t i = 0; i < n; ++i) {
        if (!infos[i].valid_data) continue;
        ++messages;
        transforms += static_cast<const tf2_msgs_msg_dds__TFMessage_*>(got[i])->transforms._length;
      }
      dds_return_loan(reader, got, n);
    }
  }
  const double seconds = simgate::bench::ns_between(started, Clock::now()) / 1e9;
  return {{"messages_per_s", static_cast<double>(messages) / seconds},
          {"transforms_per_message",
           messages ? static_cast<double>(transforms) / static_cast<double>(messages) : 0.0},
          {"seconds", seconds}};
}
#endif

json run_camera(std::uint32_t domain, const std::string& partition, const std::string& camera,
                bool raw, std::size_t count, std::size_t warmup, double timeout_s) {
  auto connection = connect(domain, partition, timeout_s, raw);
  simgate::client::DdsClient& client = *connection;
  std::vector<std::int64_t> samples;
  std::size_t errors = 0, result_bytes = 0;
  Clock::time_point started;
  for (std::size_t i = 0; i < warmup + count; ++i) {
    if (i == warmup) started = Clock::now();
    auto t0 = Clock::now();
    auto outcome =
        client.call(camera, "get_image", simgate::json::array(), std::chrono::seconds(60));
    auto t1 = Clock::now();
    const bool ok = outcome.status == simgate::Status::success && outcome.value &&
                    outcome.value->is_object() && outcome.value->contains(raw ? "width" : "image");
    if (!ok) ++errors;
    if (i >= warmup) samples.push_back(simgate::bench::ns_between(t0, t1));
    if (ok && i == warmup) result_bytes = outcome.value->dump().size();
  }
  const double seconds = simgate::bench::ns_between(started, Clock::now()) / 1e9;
  json out = simgate::bench::summarize_us(std::move(samples));
  out["frames_per_s"] = seconds > 0 ? static_cast<double>(count) / seconds : 0.0;
  out["raw"] = raw;
  out["result_bytes"] = result_bytes;
  out["errors"] = errors;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "DDS round trips: a raw Cyclone ping-pong, and simgate's DDS client against a transport "
      "host.",
      "simgate_bench_dds"};
  std::string mode, partition = "simgate-bench";
  std::uint32_t domain = 0;
  std::size_t count = 2000;
  std::optional<std::size_t> warmup;
  double timeout = 120;
  std::string camera = "rig.camera";
  bool raw = false;
  double duration = 5;
  app.add_option("--mode", mode,
                 "pong (raw server), ping (raw client), client (simgate's DdsClient) or camera "
                 "(its get_image)")
      ->required()
      ->check(CLI::IsMember({"pong", "ping", "client", "camera", "step", "ros2-step", "ros2-tf"}));
  app.add_option("--duration", duration, "ros2-tf: seconds of reading /tf")->capture_default_str();
  app.add_option("--camera", camera, "camera: the camera component")->capture_default_str();
  app.add_flag("--raw", raw,
               "camera: the client reads its images raw (DdsClientOptions::raw_images)");
  app.add_option("--domain", domain, "DDS domain")
      ->check(CLI::Range(0, 230))
      ->capture_default_str();
  app.add_option("--partition", partition, "DDS partition")->capture_default_str();
  app.add_option("--count", count, "ping, client: round trips measured")->capture_default_str();
  app.add_option("--warmup", warmup,
                 "ping, client: round trips before measuring (default count / 10)");
  app.add_option("--timeout", timeout,
                 "seconds: pong's lifetime, ping's and client's wait for the server")
      ->capture_default_str();
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  try {
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    if (mode == "pong") return run_pong(domain, partition, timeout);
#ifdef SIMGATE_BENCH_ROS2
    if (mode == "ros2-step" || mode == "ros2-tf") {
      json out = mode == "ros2-tf"
                     ? run_ros2_tf(domain, duration, timeout)
                     : run_ros2_step(domain, count, warmup.value_or(count / 10), timeout);
      out["mode"] = mode;
      std::cout << out.dump() << std::endl;
      return 0;
    }
#else
    if (mode == "ros2-step" || mode == "ros2-tf")
      throw std::runtime_error("built without the ros2 transport's protocol (protocols/ros2)");
#endif
    json out = mode == "ping"
                   ? run_ping(domain, partition, count, warmup.value_or(count / 10), timeout)
               : mode == "camera" ? run_camera(domain, partition, camera, raw, count,
                                               warmup.value_or(count / 10), timeout)
               : mode == "step"
                   ? run_step(domain, partition, count, warmup.value_or(count / 10), timeout)
                   : run_client(domain, partition, count, warmup.value_or(count / 10), timeout);
    out["mode"] = mode;
    std::cout << out.dump() << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_dds: " << e.what() << "\n";
    return 1;
  }
}
