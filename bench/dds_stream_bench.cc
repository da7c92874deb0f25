// dds_stream_bench.cc — issue #21's DDS stream target: the samples per second a reader gets
// from simgate's pose stream, against a raw Cyclone publisher of the same type (>= 0.8x).
//
// One process, Cyclone on loopback (the compiled-in loopback XML, multicast off), a partition
// of its own. One reader, best effort, keep-last 64, of `simgate/bench/pose`
// (simgate::stream::Pose) is matched, so every write is a real delivery (Cyclone delivers to
// a local reader in the writing thread); it is not read during a phase, so that no reading
// thread competes for the two cores (measured so, the rates swung threefold with the
// scheduler). A phase lasts --duration seconds; its rate is the samples written over its wall
// time:
//   - simgate: the DDS transport plugin (loaded with dlopen, as the gateway loads it) carries
//     the stream of a pose component through a StreamHub; a "simulation" thread produces a
//     sample per turn as fast as it can (under the gate, as after a step: the component
//     writes its record, the hub hands it on). Twice: with the plugin's default
//     stream_writes "direct" (the simulation thread writes it, the ratio the target is on),
//     then "thread" (the hub queues it, the DDS thread converts and writes it, printed
//     beside); written = produced - dropped (the hub counts both: a sample the DDS thread did
//     not get to before newer ones came, or that DDS refused);
//   - raw: a plain Cyclone writer of the same topic and QoS (best effort, keep-last 1) writes
//     ready-made Pose samples in a loop: what a hand-written C publisher does. Run before and
//     after the simgate phases (its rate is over both), so the order favours neither side.
// Prints one JSON object: both rates, their ratio, the samples the simulation side produced
// and the target.
//
// Threads: main (the producer, the raw writer) and the plugin's DDS thread.
#include <chrono>
#include <cstdint>
#include <iostream>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <unistd.h>

#include <dds/dds.h>

#include "bench_util.h"
#include "dds_support.h"
#include "simgate/core/component.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/core/streams.h"
#include "simgate_streams.h"

namespace {

using simgate::json;
using simgate::bench::Clock;

dds_entity_t check(dds_entity_t e, const char* what) {
  if (e < 0)
    throw std::runtime_error(std::string("DDS ") + what + ": " + simgate::dds::retcode_text(e));
  return e;
}

// A pose sensor whose sample is built as the real one's is (sim::Pose): a record of seven
// numbers.
class SyntheticPose : public simgate::Component {
 public:
  SyntheticPose() : Component("bench.pose") {
    declare_output_stream(
        "pose", {"x", "y", "z", "roll", "pitch", "yaw", "timestamp"}, [this](std::span<double> v) {
          ++n_;
          const double a = static_cast<double>(n_) * 1e-6;
          v[0] = a, v[1] = 2 * a, v[2] = 0.1, v[3] = 0, v[4] = 0, v[5] = a, v[6] = a;
        });
  }

 private:
  std::uint64_t n_ = 0;
};

// Takes what `reader` holds (its history: the latest samples); returns how many were valid.
std::uint64_t take_all(dds_entity_t reader) {
  constexpr int k_batch = 256;
  void* samples[k_batch] = {};
  dds_sample_info_t infos[k_batch];
  const dds_return_t n = dds_take(reader, samples, infos, k_batch, k_batch);
  std::uint64_t valid = 0;
  for (dds_return_t i = 0; i < n; ++i) valid += infos[i].valid_data ? 1 : 0;
  if (n > 0) dds_return_loan(reader, samples, n);
  return valid;
}

void wait_matched(dds_entity_t reader, std::uint32_t count, Clock::time_point deadline) {
  while (Clock::now() < deadline) {
    dds_subscription_matched_status_t s;
    dds_get_subscription_matched_status(reader, &s);
    if (s.current_count >= count) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  throw std::runtime_error("the reader matched no writer within 10 s");
}

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"DDS pose stream: simgate's transport against a raw Cyclone writer.",
               "simgate_bench_dds_streams"};
  double duration = 3;
  std::uint32_t domain = 0;
  app.add_option("--duration", duration, "seconds per phase")->capture_default_str();
  app.add_option("--domain", domain, "DDS domain id")->capture_default_str();
  bool no_thread_phase = false;
  app.add_flag("--no-thread-phase", no_thread_phase,
               "skip the stream_writes \"thread\" phase (to profile the others)");
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  simgate::log::set_level(simgate::log::Level::warning);
  try {
    const std::string partition = "simgate_dds_stream_bench_" + std::to_string(::getpid());
    // the reader, on a participant of its own
    simgate::dds::Participant participant(domain, simgate::dds::k_loopback_xml, "DDS stream bench");
    simgate::dds::QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), partition.c_str());
    const dds_entity_t pp = participant.handle();
    const dds_entity_t subscriber =
        check(dds_create_subscriber(pp, partition_qos.get(), nullptr), "subscriber");
    const dds_entity_t publisher =
        check(dds_create_publisher(pp, partition_qos.get(), nullptr), "publisher");
    const dds_entity_t topic = check(
        dds_create_topic(pp, &simgate_stream_Pose_desc, "simgate/bench/pose", nullptr, nullptr),
        "topic");
    simgate::dds::QosPtr reader_qos(dds_create_qos());
    dds_qset_reliability(reader_qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(reader_qos.get(), DDS_HISTORY_KEEP_LAST, 64);
    const dds_entity_t reader =
        check(dds_create_reader(subscriber, topic, reader_qos.get(), nullptr), "reader");
    const auto phase =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(duration));

    // ---- simgate: the plugin carries a hub's pose stream; `stream_writes` says who writes
    struct Phase {
      std::uint64_t written = 0, produced = 0;
      double wall = 0;
    };
    std::uint64_t received = 0;
    auto run_simgate = [&](const char* stream_writes) {
      auto gate = std::make_shared<simgate::SimulationGate>();
      auto hub = std::make_shared<simgate::StreamHub>(gate);
      SyntheticPose pose;
      hub->add(pose, "pose", {"dds"}, 1e9);  // due at every turn
      Phase out;
      auto manager = simgate::load_transport(
          "dds", {{"domain", domain}, {"partition", partition}, {"stream_writes", stream_writes}});
      manager->set_gate(gate);
      manager->set_streams(hub, "dds");
      manager->start();
      wait_matched(reader, 1, Clock::now() + std::chrono::seconds(10));
      const auto start = Clock::now();
      double t = 0;
      while (Clock::now() - start < phase) {
        std::lock_guard lock(*gate);
        hub->publish_due(t += 1e-6);
        ++out.produced;
      }
      out.wall = seconds(Clock::now() - start);
      std::this_thread::sleep_for(
          std::chrono::milliseconds(100));  // the DDS thread writes what is queued
      manager->stop();
      const simgate::StreamStatistics stats = hub->statistics().at(0);
      out.written =
          stats.samples - stats.dropped;  // neither dropped by the queue nor refused by DDS
      received += take_all(reader);
      return out;
    };
    // ---- raw: a Cyclone writer of ready-made samples, same topic and QoS
    auto run_raw = [&] {
      simgate::dds::QosPtr writer_qos(dds_create_qos());
      dds_qset_reliability(writer_qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
      dds_qset_history(writer_qos.get(), DDS_HISTORY_KEEP_LAST, 1);
      const dds_entity_t writer =
          check(dds_create_writer(publisher, topic, writer_qos.get(), nullptr), "writer");
      wait_matched(reader, 1, Clock::now() + std::chrono::seconds(10));
      simgate_stream_Pose sample{};
      sample.component = const_cast<char*>("bench.pose");
      Phase out;
      const auto start = Clock::now();
      while (Clock::now() - start < phase) {
        ++sample.seq;
        sample.time = static_cast<double>(sample.seq) * 1e-6;
        sample.x = sample.time;
        if (dds_write(writer, &sample) >= 0) ++out.written;
      }
      out.wall = seconds(Clock::now() - start);
      received += take_all(reader);
      dds_delete(writer);
      return out;
    };

    // raw before and after simgate, so that neither side is favoured by what ran first
    const Phase raw_before = run_raw();
    const Phase direct = run_simgate("direct");
    const Phase queued = no_thread_phase ? Phase{0, 0, 1} : run_simgate("thread");
    const Phase raw_after = run_raw();
    const std::uint64_t raw_count = raw_before.written + raw_after.written;
    const double raw_wall = raw_before.wall + raw_after.wall;

    const double raw_rate = raw_count / raw_wall;
    const double direct_rate = direct.written / direct.wall,
                 queued_rate = queued.written / queued.wall;
    const double ratio = raw_rate > 0 ? direct_rate / raw_rate : 0;
    std::cout << json{{"mode", "dds_streams"},
                      {"duration_s", duration},
                      {"raw_samples_per_s", raw_rate},
                      {"simgate_samples_per_s", direct_rate},
                      {"simgate_produced_per_s", direct.produced / direct.wall},
                      {"simgate_thread_samples_per_s", queued_rate},
                      {"simgate_thread_produced_per_s", queued.produced / queued.wall},
                      {"thread_ratio", raw_rate > 0 ? queued_rate / raw_rate : 0},
                      {"reader_got_samples", received > 0},
                      {"ratio", ratio},
                      {"target", {{"ratio_min", 0.8}, {"met", ratio >= 0.8}}}}
                     .dump()
              << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_dds_streams: " << e.what() << "\n";
    return 1;
  }
}
