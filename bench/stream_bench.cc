// stream_bench.cc — issue #21's stream targets for simgate_bench_sim --mode streams:
//   - 50 components streaming at 100 Hz on every transport at once keep the simulation's
//     real-time factor at 0.99 or more; the CPU it costs per 1 000 samples;
//   - the latency from the end of a step to a socket subscriber's read (p50, p99), beside
//     the sync service round trip of the same run.
//
// Gateways built as `simgate run` builds them, from an in-memory deployment: the scene --mjcf
// (the demo's) at real-time pacing with a 2 ms step, the socket, JSON-RPC and (when built)
// DDS transports on loopback, a robot `bench` (the demo's robot body) with `--components`
// components of this file's type `bench_pose`: the pose sensor, whose samples also carry
// `wall_ns`, the steady clock when the sample was read (right after the step that produced
// it). Two phases of --duration seconds each:
//   1. baseline: the same gateway without the `streams` section (nothing streams);
//   2. streams: every component streams on every transport at 100 Hz; a client thread holds
//      one socket connection per stream port and one JSON-RPC connection subscribed to every
//      stream (DDS publishes to its topics with or without readers), and reads everything.
//      Then the same thread times --calls sync calls (`time now`) on the socket transport,
//      while the streams go on;
//   3. one stream: phase 2 with a single component on the socket and JSON-RPC transports,
//      for the latency of a stream alone (with 50, one I/O thread writes 50 connections in
//      turn after each step: the later ones wait for the earlier).
// The real-time factor of a phase is the steps the loop took times the step, over the wall
// time. The CPU of a phase is the process's (getrusage) minus the client thread's own
// (CLOCK_THREAD_CPUTIME_ID): the gateway's threads only. CPU per 1 000 samples is the
// difference of the two phases over the samples the simulation produced (each one is sent
// to every subscriber of every transport), and over the samples delivered.
//
// Threads: the gateway's loop runs on the calling thread (Gateway::run); the client on a
// thread of its own with blocking sockets and poll(); bench_pose is touched only under the
// simulation lock.
#include "stream_bench.h"

#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstring>
#include <ctime>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "simgate/core/log.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/components.h"
#include "simgate/sim/registry.h"

namespace simgate::bench {
namespace {

// The pose sensor, its samples stamped with the steady clock when they are read.
class StampedPose : public sim::Pose {
 public:
  explicit StampedPose(sim::ComponentContext& c) : Pose(c) {
    declare_output_stream("pose", [this] {
      json data = get_local_data();
      data["wall_ns"] =
          std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
              .count();
      return data;
    });
  }
};

void send_all(int fd, const std::string& text) {
  if (::send(fd, text.data(), text.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(text.size()))
    throw std::runtime_error("send failed");
}

// Reads one line from a blocking socket (bounded by `deadline`), keeping what follows in `rest`.
std::string read_line(int fd, std::string& rest, Clock::time_point deadline) {
  char buffer[65536];
  for (;;) {
    if (auto nl = rest.find('\n'); nl != std::string::npos) {
      std::string line = rest.substr(0, nl);
      rest.erase(0, nl + 1);
      return line;
    }
    pollfd p{fd, POLLIN, 0};
    if (Clock::now() > deadline) throw std::runtime_error("no answer before the deadline");
    if (::poll(&p, 1, 100) <= 0) continue;
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) throw std::runtime_error("the connection closed");
    rest.append(buffer, static_cast<std::size_t>(n));
  }
}

std::uint16_t port_of(gateway::Gateway& g, const std::string& transport) {
  return endpoint_port(g.endpoints().at(transport).at(0));
}

json deployment(const std::string& mjcf, int components, bool streams, bool dds) {
  json list = json::array();
  for (int i = 0; i < components; ++i)
    list.push_back({{"name", "p" + std::to_string(i)}, {"type", "bench_pose"}, {"frequency", 100}});
  json transports = {
      {"socket", {{"plugin", "socket"}, {"options", {{"port", 0}, {"stream_port", 0}}}}},
      {"jsonrpc", {{"plugin", "jsonrpc"}, {"options", {{"port", 0}, {"stream_queue", 64}}}}}};
  std::vector<std::string> names = {"socket", "jsonrpc"};
  if (dds) {
    transports["dds"] = {
        {"plugin", "dds"},
        {"options", {{"partition", "simgate_stream_bench_" + std::to_string(::getpid())}}}};
    names.push_back("dds");
  }
  json d = {
      {"scene", {{"mjcf", mjcf}, {"timestep", 0.002}, {"realtime_factor", 1.0}}},
      {"transports", transports},
      {"robots",
       json::array(
           {{{"name", "bench"}, {"type", "robot"}, {"body", "robot"}, {"components", list}}})},
      {"services", {{"default", names}}},
      {"log_level", "warning"}};
  if (streams) d["streams"] = {{"bench.*", names}};
  return d;
}

struct StreamPhase {
  double realtime_factor = 0;
  double cpu_s = 0;  // the gateway's threads
  double wall_s = 0;
  std::uint64_t produced = 0;            // samples the simulation read
  std::uint64_t socket_lines = 0;        // samples read from the stream ports
  std::uint64_t jsonrpc_samples = 0;     // rpc.sample notifications read
  std::uint64_t dropped = 0;             // samples subscribers lost
  std::vector<std::int64_t> latency;     // step end -> socket read, ns
  std::vector<std::int64_t> round_trip;  // sync `time now` on the socket transport, ns
};

// One gateway for `duration_s`; with streams, the client reads them all, then times `calls`
// sync calls.
StreamPhase run_phase(const std::string& mjcf, int components, bool streams, bool dds,
                      double duration_s, int calls) {
  namespace gw = simgate::gateway;
  const gw::Deployment d = gw::parse_deployment(deployment(mjcf, components, streams, dds), ".");
  auto registry = sim::builtin_registry();
  registry.add<StampedPose>("bench_pose", sim::Kind::component,
                            "a pose sensor stamping its samples");
  gw::Gateway gateway(d, registry, {});
  gateway.start();
  const std::uint16_t socket_port = port_of(gateway, "socket"),
                      jsonrpc_port = port_of(gateway, "jsonrpc");

  StreamPhase phase;
  std::string error;
  double client_cpu = 0;
  double cpu0 = 0, cpu1 = 0;
  std::uint64_t steps0 = 0, steps1 = 0;
  Clock::time_point start, end;
  std::thread client([&] {
    std::vector<int> fds;
    try {
      int control = connect_loopback(socket_port);
      fds.push_back(control);
      std::string control_rest;
      std::vector<pollfd> polls;
      std::vector<std::string> rests;
      std::vector<bool> is_socket_stream;
      if (streams) {
        send_all(control, "1 simulation get_all_stream_ports []\n");
        std::string line =
            read_line(control, control_rest, Clock::now() + std::chrono::seconds(10));
        if (line.rfind("1 SUCCESS ", 0) != 0)
          throw std::runtime_error("simulation get_all_stream_ports: " + line);
        json ports = json::parse(line.substr(10));
        for (auto it = ports.begin(); it != ports.end(); ++it) {
          fds.push_back(connect_loopback(static_cast<std::uint16_t>(it->get<int>())));
          is_socket_stream.push_back(true);
        }
        int rpc = connect_loopback(jsonrpc_port);
        fds.push_back(rpc);
        is_socket_stream.push_back(false);
        std::string subscribe;
        for (int i = 0; i < components; ++i)
          subscribe +=
              R"({"jsonrpc":"2.0","method":"rpc.subscribe","params":{"component":"bench.p)" +
              std::to_string(i) + R"("},"id":)" + std::to_string(i) + "}\n";
        send_all(rpc, subscribe);
        for (std::size_t i = 1; i < fds.size(); ++i) polls.push_back({fds[i], POLLIN, 0});
        rests.resize(polls.size());
      }
      const double client_cpu0 = thread_cpu_s();
      start = Clock::now();
      cpu0 = process_cpu_s();
      steps0 = gateway.simulation().steps();
      const std::uint64_t produced0 = gateway.simulation().streams().total_samples();
      end = start +
            std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(duration_s));
      char buffer[1 << 16];
      if (!streams) std::this_thread::sleep_until(end);
      while (streams && Clock::now() < end) {
        if (::poll(polls.data(), polls.size(), 50) <= 0) continue;
        const auto now_ns =
            std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
                .count();
        for (std::size_t i = 0; i < polls.size(); ++i) {
          if (!(polls[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
          const ssize_t n = ::recv(polls[i].fd, buffer, sizeof buffer, 0);
          if (n <= 0) throw std::runtime_error("a stream connection closed");
          std::string& text = rests[i];
          text.append(buffer, static_cast<std::size_t>(n));
          std::size_t begin = 0;
          for (std::size_t nl; (nl = text.find('\n', begin)) != std::string::npos; begin = nl + 1) {
            const std::string_view line(text.data() + begin, nl - begin);
            if (is_socket_stream[i]) {
              ++phase.socket_lines;
              if (auto at = line.find("\"wall_ns\":"); at != std::string_view::npos)
                phase.latency.push_back(now_ns - std::stoll(std::string(line.substr(at + 10, 24))));
            } else if (line.find("\"rpc.sample\"") != std::string_view::npos) {
              ++phase.jsonrpc_samples;
            }
          }
          text.erase(0, begin);
        }
      }
      steps1 = gateway.simulation().steps();
      cpu1 = process_cpu_s();
      phase.produced = gateway.simulation().streams().total_samples() - produced0;
      client_cpu = thread_cpu_s() - client_cpu0;
      // the sync round trip of the same run, the streams still flowing (nobody reads them now:
      // their subscribers' queues and sockets fill, and drop)
      for (int i = 0; streams && i < calls; ++i) {
        const auto t0 = Clock::now();
        send_all(control, "r time now []\n");
        const std::string line = read_line(control, control_rest, t0 + std::chrono::seconds(10));
        phase.round_trip.push_back(ns_between(t0, Clock::now()));
        if (line.rfind("r SUCCESS", 0) != 0) throw std::runtime_error("time now: " + line);
      }
      phase.dropped = gateway.simulation().streams().total_dropped();
    } catch (const std::exception& e) {
      error = e.what();
    }
    for (int fd : fds) ::close(fd);
    gateway.stop();
  });
  gateway.run();
  client.join();
  gateway.shutdown();
  if (!error.empty()) throw std::runtime_error(error);
  phase.wall_s = std::chrono::duration<double>(end - start).count();
  phase.realtime_factor = static_cast<double>(steps1 - steps0) * 0.002 / phase.wall_s;
  phase.cpu_s = cpu1 - cpu0 - client_cpu;
  return phase;
}

}  // namespace

json run_streams(const std::string& mjcf, double duration_s, int components, int calls, bool dds) {
  log::set_level(log::Level::warning);
  const StreamPhase baseline = run_phase(mjcf, components, false, dds, duration_s, 0);
  const StreamPhase streams = run_phase(mjcf, components, true, dds, duration_s, calls);
  // the latency of one stream alone: in the run above the socket transport's one I/O thread
  // writes 50 connections in turn after each step, and the later ones wait for the earlier
  const StreamPhase single = run_phase(mjcf, 1, true, false, duration_s, calls);
  const double extra_cpu = streams.cpu_s - baseline.cpu_s;
  const std::uint64_t delivered = streams.socket_lines + streams.jsonrpc_samples;
  std::vector<std::string> transports = {"socket", "jsonrpc"};
  if (dds) transports.push_back("dds");
  return json{
      {"mode", "streams"},
      {"model", mjcf},
      {"components", components},
      {"frequency_hz", 100},
      {"transports", transports},
      {"duration_s", duration_s},
      {"realtime_factor",
       {{"baseline", baseline.realtime_factor}, {"streams", streams.realtime_factor}}},
      {"cpu_s", {{"baseline", baseline.cpu_s}, {"streams", streams.cpu_s}}},
      {"samples",
       {{"produced", streams.produced},
        {"produced_per_s", streams.produced / streams.wall_s},
        {"socket_read", streams.socket_lines},
        {"jsonrpc_read", streams.jsonrpc_samples},
        {"dropped_total", streams.dropped}}},
      {"cpu_ms_per_1000_samples_produced",
       streams.produced ? extra_cpu * 1e6 / streams.produced : 0.0},
      {"cpu_ms_per_1000_samples_delivered", delivered ? extra_cpu * 1e6 / delivered : 0.0},
      {"socket_latency_step_to_read", summarize_us(streams.latency)},
      {"socket_sync_round_trip", summarize_us(streams.round_trip)},
      {"one_stream",
       {{"socket_latency_step_to_read", summarize_us(single.latency)},
        {"socket_sync_round_trip", summarize_us(single.round_trip)}}},
      {"target", {{"realtime_factor_min", 0.99}, {"met", streams.realtime_factor >= 0.99}}}};
}

}  // namespace simgate::bench
