// The flight recorder (issue #39) in-process: the demo deployment driven step by step with
// requests, a cancel and stream commands from two "transports", recorded, then replayed on a
// second gateway built from the deployment the recording carries: every step's state is the
// recorded one, bit for bit; a recording whose one input was changed is found at that input's
// step; a recording of another model is refused, naming why.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <thread>

#include "../gateway/test_support.h"
#include "simgate/core/request_manager.h"
#include "simgate/gateway/gateway.h"
#include "simgate/mcap/reader.h"
#include "simgate/mcap/writer.h"
#include "simgate/recorder/format.h"
#include "simgate/recorder/recorder.h"
#include "simgate/recorder/replay.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/state_hash.h"

namespace simgate::recorder {
namespace {

using gateway::testing::TempDir;

// A transport of the test's own: serves every component, keeps each outcome.
class ScriptManager final : public RequestManager {
 public:
  explicit ScriptManager(std::string name) : RequestManager(std::move(name)) {}
  std::map<RequestId, Outcome> outcomes;

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    outcomes[id] = std::move(outcome);
  }
};

json deployment_document() {
  json c = gateway::testing::demo_config(0);
  c["log_level"] = "error";
  return c;
}

std::unique_ptr<gateway::Gateway> build(const json& document) {
  gateway::GatewayOptions options;
  options.check_only = true;
  static const sim::ComponentRegistry registry = sim::builtin_registry();
  return std::make_unique<gateway::Gateway>(
      gateway::parse_deployment(document, gateway::testing::source_path("config")), registry,
      options);
}

// What the script did, for the assertions.
struct Script {
  std::uint64_t steps = 0;
  std::uint64_t inputs = 0;
};

// Records `steps` steps of the demo driven by requests from two managers, a cancel, and
// commands, into `path`.
Script record_demo(const std::string& path, std::uint64_t steps) {
  const json document = deployment_document();
  auto gateway = build(document);
  sim::Simulation& sim = gateway->simulation();
  auto socket = std::make_shared<ScriptManager>("socket-like");
  auto jsonrpc = std::make_shared<ScriptManager>("jsonrpc-like");
  for (const auto& m : {socket, jsonrpc}) {
    for (const auto& e : sim.components()) m->register_component(*e->component);
  }
  sim.add_request_manager(socket, "socket");
  sim.add_request_manager(jsonrpc, "jsonrpc");

  RecordingOptions options;
  options.path = path;
  options.deployment = {
      {"document", document}, {"base_dir", gateway::testing::source_path("config")}, {"file", ""}};
  options.hash_block = 64;
  std::optional<Recorder> recorder;
  {
    std::lock_guard lock(*sim.gate());
    recorder.emplace(sim, options);
  }
  Script script;
  RequestId goto_id = 0;
  const auto call = [&](ScriptManager& m, std::string component, std::string service, json params) {
    Call c;
    c.component = std::move(component);
    c.service = std::move(service);
    c.params = std::move(params);
    c.client = 7;
    const RequestId id = m.new_request_id();
    m.run_or_submit(id, std::move(c));
    ++script.inputs;
    return id;
  };
  for (std::uint64_t i = 0; i < steps; ++i) {
    if (i == 10) call(*socket, "robot.motion", "set_speed", {0.6, 0.2});
    if (i == 150) goto_id = call(*jsonrpc, "robot.waypoint", "goto", {3.0, -2.0, 0.0, 0.3, 1.5});
    if (i == 300) {
      jsonrpc->cancel(goto_id);
      jsonrpc->process();
      ++script.inputs;
    }
    if (i == 320) call(*socket, "robot.teleport", "translate", {0.0, 0.5, 0.0});
    if (i == 400 || i == 401) {
      EXPECT_TRUE(
          sim.streams()
              .publish("robot.motion", "socket", {{"v", -0.3}, {"w", 0.5 + 0.1 * (i - 400.0)}})
              .applied);
      ++script.inputs;
    }
    if (i == 450) call(*jsonrpc, "simulation", "pause", nullptr);  // not replayed: loop control
    if (i == 460) call(*jsonrpc, "no_such", "service", nullptr);   // refused alike in the replay
    {
      std::lock_guard lock(*sim.gate());
      sim.step();
    }
    ++script.steps;
  }
  const json status = recorder->finish();
  EXPECT_TRUE(status["error"].is_null()) << status.dump();
  EXPECT_EQ(status["steps"], steps);
  EXPECT_EQ(status["inputs"], script.inputs);
  return script;
}

ReplayReport replay(const std::string& path) {
  const Recording recording = Recording::read(path);
  EXPECT_TRUE(recording.complete);
  auto gateway = build(recording.deployment.at("document"));
  Replayer replayer(gateway->simulation(), recording);
  return replayer.run();
}

TEST(Recorder, AReplayOfARecordedRunIsTheSameRunBitForBit) {
  TempDir dir;
  const std::string path = dir.file("run.mcap");
  const Script script = record_demo(path, 600);
  const ReplayReport report = replay(path);
  EXPECT_FALSE(report.mismatch) << report.to_json().dump();
  EXPECT_EQ(report.steps, script.steps);
  EXPECT_EQ(report.steps_compared, script.steps);
  EXPECT_EQ(report.inputs_applied + report.inputs_skipped, script.inputs);
  EXPECT_EQ(report.inputs_skipped, 1u);  // simulation pause
  EXPECT_EQ(report.outcomes_differing, 0u);
}

TEST(Recorder, TheRecordingHoldsWhatItsFormatSays) {
  TempDir dir;
  const std::string path = dir.file("run.mcap");
  record_demo(path, 200);
  mcap::Reader reader(path);
  mcap::Item item;
  std::map<std::string, int> messages;
  std::vector<std::string> attachments;
  while (reader.next(item)) {
    if (auto* m = std::get_if<mcap::Message>(&item))
      ++messages[reader.channel(m->channel_id)->topic];
    if (auto* a = std::get_if<mcap::Attachment>(&item)) attachments.push_back(a->name);
  }
  EXPECT_TRUE(reader.complete());
  EXPECT_EQ(messages[k_initial_state_topic], 1);
  EXPECT_EQ(messages[k_hashes_topic], 4);    // 200 steps in blocks of 64
  EXPECT_EQ(messages[k_inputs_topic], 2);    // set_speed, goto
  EXPECT_EQ(messages[k_outcomes_topic], 1);  // set_speed's (the goto still runs)
  EXPECT_GT(messages["/robot/pose"], 0) << "the pose stream";
  // the bodies for Foxglove's 3D panel, from the simulation's body_poses stream
  EXPECT_EQ(messages["/scene"], 1);
  EXPECT_GT(messages["/tf"], 0);
  EXPECT_EQ(messages["/simulation"], 0);  // its body_poses samples are the /tf messages
  EXPECT_EQ(attachments.front(), k_deployment_attachment);
}

// Copies `from` to `to`, changing the input message whose "seq" is `seq` by `change`.
void copy_changing(const std::string& from, const std::string& to, std::uint64_t seq,
                   const std::function<void(json&)>& change) {
  mcap::Reader reader(from);
  mcap::Writer writer(to, {});
  std::map<std::uint16_t, std::uint16_t> schemas{{0, 0}}, channels;
  mcap::Item item;
  while (reader.next(item)) {
    if (auto* s = std::get_if<mcap::Schema>(&item)) {
      schemas[s->id] = writer.add_schema(s->name, s->encoding, s->data);
    } else if (auto* c = std::get_if<mcap::Channel>(&item)) {
      channels[c->id] =
          writer.add_channel(schemas.at(c->schema_id), c->topic, c->message_encoding, c->metadata);
    } else if (auto* m = std::get_if<mcap::Message>(&item)) {
      std::string data = m->data;
      if (reader.channel(m->channel_id)->topic == k_inputs_topic) {
        json input = json::parse(data);
        if (input["seq"] == seq) {
          change(input);
          data = input.dump();
        }
      }
      writer.write(channels.at(m->channel_id), m->sequence, m->log_time, m->publish_time, data);
    } else if (auto* a = std::get_if<mcap::Attachment>(&item)) {
      writer.attach(a->log_time, a->create_time, a->name, a->media_type, a->data);
    } else if (auto* md = std::get_if<mcap::MetadataRecord>(&item)) {
      writer.add_metadata(md->name, md->metadata);
    }
  }
  writer.close();
}

TEST(Recorder, AChangedInputIsFoundAtItsStep) {
  TempDir dir;
  const std::string path = dir.file("run.mcap");
  record_demo(path, 500);
  // the teleport (the fourth input, at step 320) goes elsewhere
  const Recording original = Recording::read(path);
  std::uint64_t seq = 0, step = 0;
  for (const json& in : original.inputs)
    if (in.value("service", "") == "translate") {
      seq = in["seq"];
      step = in["step"];
    }
  ASSERT_EQ(step, 320u);
  const std::string changed = dir.file("changed.mcap");
  copy_changing(path, changed, seq, [](json& in) { in["params"] = {0.0, 0.50001, 0.0}; });
  const ReplayReport report = replay(changed);
  ASSERT_TRUE(report.mismatch);
  EXPECT_EQ(report.mismatch->step, step + 1);  // the state after the step that followed it
  ASSERT_EQ(report.mismatch->inputs.size(), 1u);
  EXPECT_EQ(report.mismatch->inputs[0]["service"], "translate");
  EXPECT_NE(
      std::find(report.mismatch->quantities.begin(), report.mismatch->quantities.end(), "qpos"),
      report.mismatch->quantities.end());
  EXPECT_EQ(report.steps, step + 1);  // it stopped there
}

TEST(Recorder, AnotherModelIsRefusedNamingWhy) {
  TempDir dir;
  const std::string path = dir.file("run.mcap");
  record_demo(path, 10);
  const Recording recording = Recording::read(path);
  json other = deployment_document();
  other["scene"]["mjcf"] = gateway::testing::source_path("tests/models/tendon_arm.xml");
  other["robots"] = json::array();
  other.erase("streams");
  auto gateway = build(other);
  try {
    Replayer replayer(gateway->simulation(), recording);
    FAIL() << "replayed on another model";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("the model is not the recording's"), std::string::npos)
        << e.what();
  }
}

// A spawn compiles its model on a worker thread and takes it in on the simulation's turn
// after it is done (wall-clock dependent): the replay takes it in at the recorded step.
TEST(Recorder, ASpawnDuringTheRecordingIsTakenInAtItsStep) {
  TempDir dir;
  const std::string path = dir.file("spawn.mcap");
  json document = deployment_document();
  document["streams"]["ball*"] = {"socket"};  // the spawned robot's pose streams
  {
    auto gateway = build(document);
    sim::Simulation& sim = gateway->simulation();
    auto manager = std::make_shared<ScriptManager>("script");
    for (const auto& e : sim.components()) manager->register_component(*e->component);
    sim.add_request_manager(manager, "script");
    RecordingOptions options;
    options.path = path;
    options.deployment = {{"document", document},
                          {"base_dir", gateway::testing::source_path("config")},
                          {"file", ""}};
    std::optional<Recorder> recorder;
    {
      std::lock_guard lock(*sim.gate());
      recorder.emplace(sim, options);
    }
    for (int i = 0; i < 400; ++i) {
      if (i == 50) {
        Call c{"simulation",
               "spawn_entity",
               {{"name", "ball"},
                {"mjcf", "<body><freejoint/><geom type='sphere' size='0.1' mass='1'/></body>"},
                {"pose", {1.0, 1.0, 0.6}},
                {"robot",
                 {{"type", "robot"},
                  {"components", json::array({{{"name", "pose"}, {"type", "pose"}}})}}}}};
        manager->run_or_submit(manager->new_request_id(), std::move(c));
      }
      if (i == 100) {  // the compile's end (wall clock) is awaited here: the model lands now
        const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        while (sim.soon_count() == 0 && std::chrono::steady_clock::now() < until)
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      sim.process_requests();  // the loop's turn: a finished compile is taken in here
      std::lock_guard lock(*sim.gate());
      sim.step();
      if (i == 100) {
        ASSERT_EQ(sim.model_generation(), 1u) << "the spawn landed";
      }
    }
    recorder->finish();
    ASSERT_EQ(manager->outcomes.size(), 1u);
    EXPECT_EQ(manager->outcomes.begin()->second.status, Status::success);
  }
  const Recording recording = Recording::read(path);
  std::size_t tasks = 0;
  for (const json& in : recording.inputs) tasks += in["type"] == "tasks";
  EXPECT_EQ(tasks, 1u);
  // the spawned robot's stream is recorded from the step its model came in
  mcap::Reader reader(path);
  mcap::Item item;
  int ball_poses = 0;
  while (reader.next(item))
    if (auto* m = std::get_if<mcap::Message>(&item))
      ball_poses += reader.channel(m->channel_id)->topic == "/ball/pose";
  EXPECT_GT(ball_poses, 30) << "300 steps of 2 ms at 60 Hz";
  const ReplayReport report = replay(path);
  EXPECT_FALSE(report.mismatch) << report.to_json().dump();
  EXPECT_EQ(report.steps, 400u);
  EXPECT_EQ(report.steps_compared, 400u);
}

TEST(Recorder, AFullDiskStopsTheRecordingWithAnErrorAndTheSimulationGoesOn) {
  // /dev/full: every write fails with ENOSPC
  auto gateway = build(deployment_document());
  sim::Simulation& sim = gateway->simulation();
  RecordingOptions options;
  options.path = "/dev/full";
  std::optional<Recorder> recorder;
  {
    std::lock_guard lock(*sim.gate());
    recorder.emplace(sim, options);
  }
  for (int i = 0; i < 300; ++i) {
    std::lock_guard lock(*sim.gate());
    sim.step();
  }
  const json status = recorder->finish();
  ASSERT_TRUE(status["error"].is_string()) << status.dump();
  EXPECT_NE(status["error"].get<std::string>().find("No space left on device"), std::string::npos)
      << status.dump();
  EXPECT_FALSE(status["recording"].get<bool>());
  EXPECT_EQ(sim.steps(), 300u);  // every step taken
}

// The fingerprints: a change of one bit of one value shows in that quantity's hash alone.
TEST(StateHasher, TheLeastChangeOfAQuantityShowsInItsOwnHashAlone) {
  auto gateway = build(deployment_document());
  sim::Simulation& sim = gateway->simulation();
  const mjModel* m = sim.m();
  mjData* d = sim.d();
  sim::StateHasher hasher(m);
  const auto& names = hasher.quantities();
  for (const char* q : {"time", "qpos", "qvel", "warmstart", "ctrl", "qfrc_applied"})
    EXPECT_NE(std::find(names.begin(), names.end(), q), names.end()) << q;
  std::vector<std::uint32_t> before(names.size()), after(names.size());
  hasher.hash(m, d, before);
  const auto changed = [&]() {
    hasher.hash(m, d, after);
    std::vector<std::string> out;
    for (std::size_t i = 0; i < names.size(); ++i)
      if (after[i] != before[i]) out.push_back(names[i]);
    return out;
  };
  // the last value of a long array, one ulp
  mjtNum& last = d->qpos[m->nq - 1];
  const mjtNum saved = last;
  last = std::nextafter(last, 1e9);
  EXPECT_EQ(changed(), std::vector<std::string>{"qpos"});
  last = saved;
  EXPECT_TRUE(changed().empty());
  // -0.0 is not 0.0 (bytes, not values)
  const mjtNum ctrl = d->ctrl[0];
  d->ctrl[0] = ctrl == 0 ? -0.0 : -ctrl;
  EXPECT_EQ(changed(), std::vector<std::string>{"ctrl"});
  d->ctrl[0] = ctrl;
  d->xfrc_applied[6 * m->nbody - 1] += 1e-300;
  EXPECT_EQ(changed(), std::vector<std::string>{"xfrc_applied"});
}

TEST(Recorder, AFileThatIsNoRecordingIsAClearError) {
  TempDir dir;
  const std::string text = dir.write("notes.mcap", "these are not the droids\n");
  EXPECT_THROW(Recording::read(text), mcap::ReadError);
  // an MCAP file, but no simgate recording
  const std::string other = dir.file("other.mcap");
  {
    mcap::Writer w(other, {});
    w.write(w.add_channel(0, "/x", "json"), 1, 0, 0, "{}");
  }
  try {
    Recording::read(other);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not a simgate recording"), std::string::npos);
  }
}

}  // namespace
}  // namespace simgate::recorder
