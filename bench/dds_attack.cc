// dds_attack.cc — the DDS side of bench/attacks (issue #17's attack list, re-run).
//
// Its raw Cyclone client (dds_raw_client.h) speaks simgate's wire types
// (protocols/dds/simgate_dds.idl) with no DdsClient in between, so that it can send what a
// well-behaved client never sends: params nested 80 000 deep, another client's id or a zero
// id, a duplicate seq, names of 10 MB, and a reply reader that never takes. One mode per run;
// each prints one JSON object on stdout.
//
//   deep      params 80 000 deep (arrays, then objects) to `human move`, then a normal call
//   hijack    a spoofer calls with the owner's id, cancels the owner's `time sleep` with the
//             owner's id, and calls with id zero; the owner's call then ends on its own
//   stuck     a reply reader that never takes (it holds --max-samples replies, 0 = any
//             number): writes --count calls, prints {"ready": true}, then stays (until
//             SIGTERM or --hold seconds); stopped with SIGSTOP, it is a frozen client process.
//             The calls: --component --service (default robot.pose get_local_data)
//   good      simgate's DdsClient: --count calls of `simulation list_robots`, one after the
//             other; answered, failed, total and slowest call
//   names     a component name, then a service name, of 10 MiB each
//   dupseq    a second call under the seq of a running async call (`time sleep`)
//   utf8      params whose error preview would cut a UTF-8 character
//   sessions  --count client sessions one after another (participant, writer, reader, one
//             call, gone), as `simgate call` in a loop makes them
//   call      one call: --component --service --params
//   pipeline  --count calls written back to back without reading (--component --service
//             --params, default simulation list_robots), then every reply read: final replies
//             per seq (answered, refused Overloaded, other, missing, doubled) out of sent
//   cancelseq (issue #35) `time sleep 1` under seq 5, then an OP_CANCEL under the same seq 5
//             targeting it: every reply for seq 5 (one final reply expected, not two)
//   command   (issue #35) one JsonCommand of --bytes bytes (a JSON object, `{"v": [1,1,...]}`)
//             on the input stream of --component (default robot.motion), then a normal call
//             (the server still serves); print the server's peak resident size with
//             --server-pid (VmHWM of /proc/PID/status, before and after)
//
// Usage: simgate_bench_dds_attack --mode MODE --domain D --partition P [--count N]
//        [--max-samples N] [--hold S] [--timeout S] [--component C --service S --params JSON]
//        [--bytes N --server-pid PID]
// Cyclone stays on loopback (the compiled-in config/dds/loopback.xml). Every wait is bounded
// by --timeout (default 20 s).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "bench_util.h"
#include "dds_raw_client.h"
#include "dds_support.h"
#include "simgate/client/dds_client.h"
#include "simgate_streams.h"

namespace {

using simgate::bench::Clock;
using simgate::bench::json;
namespace sd = simgate::dds;
// the raw client (dds_raw_client.h)
using simgate::bench::g_timeout;
using simgate::bench::ms_since;
using simgate::bench::RawClient;
using simgate::bench::ready_client;
using simgate::bench::reply_json;

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop.store(true); }

json mode_deep(std::uint32_t domain, const std::string& partition) {
  auto c = ready_client(domain, partition);
  constexpr std::size_t k_deep = 80000;
  const std::string arrays = std::string(k_deep, '[') + std::string(k_deep, ']');
  std::string objects = "{\"speed\":";
  for (std::size_t i = 1; i < k_deep; ++i) objects += "{\"a\":";
  objects += "1" + std::string(k_deep, '}');
  json out;
  out["params_bytes"] = {arrays.size(), objects.size()};
  c->write(1, simgate_OP_CALL, "human", "move", arrays);
  out["arrays"] = reply_json(c->final_reply(1));
  c->write(2, simgate_OP_CALL, "human", "move", objects);
  out["objects"] = reply_json(c->final_reply(2));
  c->write(3, simgate_OP_CALL, "simulation", "list_robots", "");
  out["after"] = reply_json(c->final_reply(3));
  return out;
}

json mode_hijack(std::uint32_t domain, const std::string& partition) {
  auto owner = ready_client(domain, partition);
  auto spoofer = ready_client(domain, partition);
  json out;
  out["owner_id"] = sd::to_hex(owner->id());
  out["spoofer_id"] = sd::to_hex(spoofer->id());
  // the spoofer calls as the owner before the owner ever did
  spoofer->write(1, simgate_OP_CALL, "simulation", "list_robots", "", 0, &owner->id());
  out["spoofed_call"] = reply_json(spoofer->final_reply(1));
  // the owner starts an async call; the spoofer tries to cancel it under the owner's id
  owner->write(1, simgate_OP_CALL, "time", "sleep", "[1.0]");
  out["owner_accepted"] = reply_json(owner->next());
  spoofer->write(2, simgate_OP_CANCEL, "", "", "", 1, &owner->id());
  out["spoofed_cancel"] = reply_json(spoofer->final_reply(2));
  // a zero id
  const sd::ClientId zero{};
  spoofer->write(3, simgate_OP_CALL, "simulation", "list_robots", "", 0, &zero);
  out["zero_id"] = reply_json(spoofer->final_reply(3));
  // the owner's sleep ends on its own (not PREEMPTED by the spoofer)
  out["owner_final"] = reply_json(owner->final_reply(1));
  return out;
}

json mode_stuck(std::uint32_t domain, const std::string& partition, int count, int max_samples,
                double hold_s, const std::string& component, const std::string& service) {
  RawClient c(domain, partition);
  c.create_reply_reader(max_samples > 0 ? max_samples : DDS_LENGTH_UNLIMITED);  // never takes
  if (!c.wait_matched())
    throw std::runtime_error("no simgate DDS server matched in partition '" + partition + "'");
  for (int i = 1; i <= count; ++i) c.write(i, simgate_OP_CALL, component, service, "");
  std::cout << json{{"ready", true}, {"id", sd::to_hex(c.id())}, {"written", count}}.dump()
            << std::endl;
  const auto until = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(hold_s));
  while (!g_stop.load() && Clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  c.drain(std::chrono::seconds(5));
  return {{"held_s", hold_s}};
}

json mode_good(std::uint32_t domain, const std::string& partition, int count) {
  simgate::client::DdsClientOptions options;
  options.domain = domain;
  options.partition = partition;
  options.discovery_timeout = g_timeout;
  simgate::client::DdsClient client(options);
  if (!client.wait_for_server(g_timeout)) throw std::runtime_error("DdsClient: no server");
  int answered = 0, failed = 0;
  double slowest = 0;
  json first;
  const auto t0 = Clock::now();
  for (int i = 0; i < count; ++i) {
    const auto t = Clock::now();
    try {
      auto o = client.call("simulation", "list_robots", nullptr, std::chrono::seconds(5));
      if (o.status == simgate::Status::success)
        ++answered;
      else
        ++failed;
      if (i == 0) first = o.value ? *o.value : json(o.message);
    } catch (const std::exception& e) {
      ++failed;
      if (i == 0) first = e.what();
    }
    slowest = std::max(slowest, ms_since(t));
  }
  return {{"calls", count},           {"answered", answered},  {"failed", failed},
          {"total_ms", ms_since(t0)}, {"slowest_ms", slowest}, {"first", first}};
}

json mode_names(std::uint32_t domain, const std::string& partition) {
  auto c = ready_client(domain, partition);
  const std::string huge(10u << 20, 'c');
  json out;
  c->write(1, simgate_OP_CALL, huge, "move", "[1, 0]");
  out["component"] = reply_json(c->final_reply(1));
  c->write(2, simgate_OP_CALL, "human", huge, "[1, 0]");
  out["service"] = reply_json(c->final_reply(2));
  c->write(3, simgate_OP_CALL, "simulation", "list_robots", "");
  out["after"] = reply_json(c->final_reply(3));
  return out;
}

json mode_dupseq(std::uint32_t domain, const std::string& partition) {
  auto c = ready_client(domain, partition);
  json out, replies = json::array();
  c->write(5, simgate_OP_CALL, "time", "sleep", "[0.5]");
  out["accepted"] = reply_json(c->next());
  c->write(5, simgate_OP_CALL, "simulation", "list_robots", "");
  // every reply for seq 5 until the final one (or the timeout)
  for (int i = 0; i < 4; ++i) {
    auto r = c->next();
    if (!r) break;
    replies.push_back(r->to_json());
    if (r->last) break;
  }
  out["replies_after_duplicate"] = replies;
  return out;
}

json mode_utf8(std::uint32_t domain, const std::string& partition) {
  auto c = ready_client(domain, partition);
  std::string params = "a";
  for (int i = 0; i < 40; ++i) params += "\xc3\xa9";  // e acute: byte 60 falls inside one
  c->write(1, simgate_OP_CALL, "human", "move", params);
  return {{"reply", reply_json(c->final_reply(1))}};
}

json mode_sessions(std::uint32_t domain, const std::string& partition, int count) {
  int answered = 0;
  const auto t0 = Clock::now();
  for (int i = 0; i < count && !g_stop.load(); ++i) {
    RawClient c(domain, partition);
    c.create_reply_reader();
    if (!c.wait_matched()) continue;
    c.write(1, simgate_OP_CALL, "simulation", "list_robots", "");
    auto r = c.final_reply(1, std::chrono::seconds(5));
    if (r && r->status == simgate_ST_SUCCESS) ++answered;
  }
  return {{"sessions", count}, {"answered", answered}, {"total_ms", ms_since(t0)}};
}

json mode_call(std::uint32_t domain, const std::string& partition, const std::string& component,
               const std::string& service, const std::string& params) {
  auto c = ready_client(domain, partition);
  c->write(1, simgate_OP_CALL, component, service, params);
  return {{"reply", reply_json(c->final_reply(1))}};
}

json mode_pipeline(std::uint32_t domain, const std::string& partition, int count,
                   const std::string& component, const std::string& service,
                   const std::string& params) {
  auto c = ready_client(domain, partition);
  const auto t0 = Clock::now();
  for (int i = 1; i <= count; ++i) c->write(i, simgate_OP_CALL, component, service, params);
  const double write_ms = ms_since(t0);
  std::vector<int> finals(count + 1, 0);
  int answered = 0, overloaded = 0, other = 0, seen = 0;
  json first_other;
  while (seen < count) {
    auto r = c->next(std::chrono::seconds(15));  // the server parks a reply at most 10 s
    if (!r) break;
    if (!r->last || r->seq < 1 || r->seq > static_cast<std::uint64_t>(count)) continue;
    if (finals[r->seq]++ == 0) ++seen;
    if (r->status == simgate_ST_SUCCESS) {
      ++answered;
    } else if (r->message.rfind("Overloaded", 0) == 0) {
      ++overloaded;
    } else if (other++ == 0) {
      first_other = r->to_json();
    }
  }
  int missing = 0, doubled = 0;
  for (int i = 1; i <= count; ++i) missing += finals[i] == 0, doubled += finals[i] > 1;
  return {{"sent", count},        {"final_replies", seen},
          {"answered", answered}, {"overloaded", overloaded},
          {"other", other},       {"first_other", first_other},
          {"missing", missing},   {"doubled", doubled},
          {"write_ms", write_ms}, {"total_ms", ms_since(t0)}};
}

json mode_cancelseq(std::uint32_t domain, const std::string& partition) {
  auto c = ready_client(domain, partition);
  json out, replies = json::array();
  c->write(5, simgate_OP_CALL, "time", "sleep", "[1.0]");
  out["accepted"] = reply_json(c->next());
  c->write(5, simgate_OP_CANCEL, "", "", "", 5);
  // every reply for seq 5 until none came for 2 s (the sleep ends within 1 s either way)
  int finals = 0;
  while (auto r = c->next(std::chrono::seconds(2))) {
    if (r->seq != 5) continue;
    replies.push_back(r->to_json());
    finals += r->last;
  }
  out["replies_after_cancel"] = replies;
  out["final_replies"] = finals;
  return out;
}

// VmHWM (peak resident set, kB) of process `pid`, or -1.
long peak_rss_kb(int pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

json mode_command(std::uint32_t domain, const std::string& partition, const std::string& component,
                  std::size_t bytes, int server_pid) {
  auto c = ready_client(domain, partition);
  json out;
  out["peak_rss_kb_before"] = server_pid > 0 ? peak_rss_kb(server_pid) : -1;
  // a writer of the stream's JsonCommand topic, matched by the server's command reader
  sd::Participant participant(domain, sd::k_loopback_xml, "attack command writer");
  dds_entity_t pp = participant.handle();
  sd::QosPtr partition_qos(dds_create_qos());
  dds_qset_partition1(partition_qos.get(), partition.c_str());
  dds_entity_t publisher = dds_create_publisher(pp, partition_qos.get(), nullptr);
  // the stream's command topic: "simgate/" + the component with '.' as '/' (docs/transports/dds.md)
  std::string topic_name = "simgate/" + component + "/json";
  std::replace(topic_name.begin(), topic_name.end(), '.', '/');
  dds_entity_t topic =
      dds_create_topic(pp, &simgate_stream_JsonCommand_desc, topic_name.c_str(), nullptr, nullptr);
  sd::QosPtr qos = sd::make_qos(false, 0, DDS_SECS(10));
  dds_entity_t writer = dds_create_writer(publisher, topic, qos.get(), nullptr);
  if (writer < 0) throw std::runtime_error("command writer: " + sd::retcode_text(writer));
  const auto deadline = Clock::now() + g_timeout;
  dds_publication_matched_status_t matched{};
  while (Clock::now() < deadline && matched.current_count == 0) {
    dds_get_publication_matched_status(writer, &matched);
    dds_sleepfor(DDS_MSECS(2));
  }
  if (matched.current_count == 0)
    throw std::runtime_error("no reader of " + topic_name + " matched");
  // {"v": [1,1,1,...]}: a JSON object of `bytes` bytes, most of it a long array of small numbers
  std::string text = "{\"v\": [1";
  while (text.size() + 4 < bytes) text += ",1";
  text += "]}";
  simgate_stream_JsonCommand command{};
  command.json = text.data();
  const auto t0 = Clock::now();
  dds_return_t rc = dds_write(writer, &command);
  out["command_bytes"] = text.size();
  out["write"] = sd::retcode_text(rc);
  out["acknowledged"] = dds_wait_for_acks(writer, DDS_SECS(20)) == DDS_RETCODE_OK;
  out["ack_ms"] = ms_since(t0);
  // the server still serves
  c->write(1, simgate_OP_CALL, "simulation", "list_robots", "");
  out["after"] = reply_json(c->final_reply(1));
  if (server_pid > 0) out["peak_rss_kb_after"] = peak_rss_kb(server_pid);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "The DDS attacks of bench/attacks (issue #17), as a raw Cyclone client of simgate's wire "
      "types.",
      "simgate_bench_dds_attack"};
  std::string mode, partition = "simgate", component, service, params;
  std::uint32_t domain = 0;
  int count = 20, max_samples = 1, server_pid = 0;
  std::size_t bytes = 20u << 20;
  double hold = 30, timeout = 20;
  app.add_option("--mode", mode,
                 "deep, hijack, stuck, good, names, dupseq, utf8, sessions, call, pipeline, "
                 "cancelseq or command")
      ->required()
      ->check(CLI::IsMember({"deep", "hijack", "stuck", "good", "names", "dupseq", "utf8",
                             "sessions", "call", "pipeline", "cancelseq", "command"}));
  app.add_option("--domain", domain, "DDS domain")
      ->check(CLI::Range(0, 230))
      ->capture_default_str();
  app.add_option("--partition", partition, "DDS partition")->capture_default_str();
  app.add_option("--count", count,
                 "stuck, pipeline: calls written; good: calls made; sessions: sessions")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--max-samples", max_samples, "stuck: replies its reader holds (0: no limit)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  app.add_option("--hold", hold, "stuck: seconds to stay (SIGTERM ends it sooner)")
      ->capture_default_str();
  app.add_option("--timeout", timeout, "seconds: every wait (a server, a reply)")
      ->capture_default_str();
  app.add_option("--component", component,
                 "call, stuck, pipeline: component; command: the input stream's");
  app.add_option("--service", service, "call, stuck, pipeline: service");
  app.add_option("--params", params, "call, pipeline: params (JSON text)");
  app.add_option("--bytes", bytes, "command: size of the JsonCommand's text")
      ->capture_default_str();
  app.add_option("--server-pid", server_pid,
                 "command: the server process, for its peak resident size");
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  g_timeout = std::chrono::milliseconds(static_cast<long long>(timeout * 1000));
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    json out;
    if (mode == "deep")
      out = mode_deep(domain, partition);
    else if (mode == "hijack")
      out = mode_hijack(domain, partition);
    else if (mode == "stuck")
      out = mode_stuck(domain, partition, count, max_samples, hold,
                       component.empty() ? "robot.pose" : component,
                       service.empty() ? "get_local_data" : service);
    else if (mode == "good")
      out = mode_good(domain, partition, count);
    else if (mode == "names")
      out = mode_names(domain, partition);
    else if (mode == "dupseq")
      out = mode_dupseq(domain, partition);
    else if (mode == "utf8")
      out = mode_utf8(domain, partition);
    else if (mode == "sessions")
      out = mode_sessions(domain, partition, count);
    else if (mode == "pipeline")
      out = mode_pipeline(domain, partition, count, component.empty() ? "simulation" : component,
                          service.empty() ? "list_robots" : service, params);
    else if (mode == "cancelseq")
      out = mode_cancelseq(domain, partition);
    else if (mode == "command")
      out = mode_command(domain, partition, component.empty() ? "robot.motion" : component, bytes,
                         server_pid);
    else
      out = mode_call(domain, partition, component, service, params);
    out["mode"] = mode;
    std::cout << out.dump(-1, ' ', false, json::error_handler_t::replace) << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cout << json{{"mode", mode}, {"error", e.what()}}.dump(-1, ' ', false,
                                                                json::error_handler_t::replace)
              << std::endl;
    std::cerr << "simgate_bench_dds_attack: " << e.what() << "\n";
    return 1;
  }
}
