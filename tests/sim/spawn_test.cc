// SimSpawn: `simulation spawn_entity` / `delete_entity` on the demo scene (spawn.cc): the
// model is recompiled off the simulation thread and swapped in between two steps, state and
// requests in flight carried across; every bad input is refused and changes nothing.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "sim_fixture.h"
#include "simgate/core/streams.h"

namespace simgate::sim {
namespace {

constexpr const char* k_spawn_ball =
    R"(<body><freejoint/><geom type="sphere" size="0.1" mass="1"/></body>)";

class SimSpawnTest : public testing::DemoSim {
 protected:
  // Waits for `id` taking no step (the loop's turns while paused: requests and run_soon
  // tasks only), so that nothing moves however long the worker compiles. Bounded.
  std::optional<Outcome> answer_without_stepping(RequestId id) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    std::optional<Outcome> o;
    while (!o && std::chrono::steady_clock::now() < deadline) {
      sim_->process_requests();
      o = rm_->outcome(id);
      if (!o) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return o;
  }
  Outcome spawn(const std::string& name, json pose = {1.0, 1.0, 0.5},
                const std::string& mjcf = k_spawn_ball) {
    return finish(rm_->call("simulation", "spawn_entity", {name, mjcf, std::move(pose)}));
  }
  Outcome remove(const std::string& name) {
    return finish(rm_->call("simulation", "delete_entity", {name}));
  }

  // A refused request: FAILED, bad arguments, naming `parameter`, and the world unchanged.
  void expect_refused(const Outcome& o, const std::string& parameter, const std::string& why) {
    EXPECT_EQ(o.status, Status::failed);
    EXPECT_EQ(o.failure, Failure::bad_arguments) << o.message;
    EXPECT_EQ(o.data.is_object() ? o.data.value("parameter", "") : "", parameter) << o.message;
    EXPECT_NE(o.message.find(why), std::string::npos) << o.message;
    EXPECT_EQ(sim_->model_generation(), generation_);
    EXPECT_EQ(sim_->m()->nbody, nbody_);
    EXPECT_TRUE(testing::state_is_finite(*sim_));
  }
  void remember_world() {
    generation_ = sim_->model_generation();
    nbody_ = sim_->m()->nbody;
  }

  std::uint64_t generation_ = 0;  // model generation before a refused request
  int nbody_ = 0;                 // bodies before a refused request
};

TEST_F(SimSpawnTest, SpawnedBodyAppearsInSceneObjectsAtItsPose) {
  Outcome o = spawn("ball", {1.0, 2.0, 0.5, 0.0, 0.0, 0.7071067811865476, 0.7071067811865476});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(o.value->at("name"), "ball");
  EXPECT_EQ(o.value->at("model_generation"), 1);
  EXPECT_EQ(sim_->model_generation(), 1u);
  json objects = call("simulation", "get_scene_objects").value.value();
  ASSERT_TRUE(objects.contains("ball")) << objects.dump();
  EXPECT_NEAR(objects["ball"][1][0].get<double>(), 1.0, 1e-6);
  EXPECT_NEAR(objects["ball"][1][1].get<double>(), 2.0, 1e-6);
  // [qx, qy, qz, qw]: a quarter turn about z, as given
  EXPECT_NEAR(objects["ball"][2][2].get<double>(), 0.7071067811865476, 1e-6);
  EXPECT_NEAR(objects["ball"][2][3].get<double>(), 0.7071067811865476, 1e-6);
  // it is a physical body: it falls to the floor
  run_for(1.0);
  objects = call("simulation", "get_scene_objects").value.value();
  EXPECT_NEAR(objects["ball"][1][2].get<double>(), 0.1, 0.01);
}

// A paused simulation takes no step: the change is swapped in on the simulation's next turn
// (Simulation::run_soon), not at a step. Before, it waited for `play` or `step` for ever.
TEST_F(SimSpawnTest, ASpawnWhilePausedCompletesWithoutAStep) {
  ASSERT_EQ(call("simulation", "pause").status, Status::success);
  const std::uint64_t steps = sim_->steps();
  const double time = sim_->sim_time();
  auto o = answer_without_stepping(
      rm_->call("simulation", "spawn_entity", {"ball", k_spawn_ball, {1.0, 1.0, 0.5}}));
  ASSERT_TRUE(o.has_value()) << "spawn_entity not answered while paused";
  EXPECT_EQ(o->status, Status::success) << o->message;
  EXPECT_EQ(sim_->steps(), steps);
  EXPECT_EQ(sim_->sim_time(), time);
  EXPECT_TRUE(call("simulation", "get_scene_objects").value->contains("ball"));
}

TEST_F(SimSpawnTest, StateAndTimeAreCarriedAcross) {
  call("robot.motion", "set_speed", {0.5, 0.2});
  run_for(0.5);
  const json before = pose();
  const double time = sim_->sim_time();
  const double left = sim_->d()->ctrl[sim_->model().actuator_id("robot_left_motor")];
  ASSERT_EQ(spawn("ball").status, Status::success);
  // the robot is where it was (the steps taken while compiling moved it on, so compare
  // with a tolerance the worker's time allows) and its wheels still turn
  EXPECT_GE(sim_->sim_time(), time);
  EXPECT_EQ(sim_->d()->ctrl[sim_->model().actuator_id("robot_left_motor")], left);
  const json after = pose();
  EXPECT_GT(after["x"].get<double>(), before["x"].get<double>() - 1e-9);
  run_for(0.5);
  EXPECT_GT(pose()["x"].get<double>(), after["x"].get<double>());
}

TEST_F(SimSpawnTest, RequestInFlightCompletesAcrossSpawnAndDelete) {
  RequestId go = rm_->call("robot.waypoint", "goto", {1.5, 0.0, 0.0, 0.2, 1.0});
  sim_->process_requests();
  ASSERT_EQ(spawn("ball", {-1.0, -1.0, 0.5}).status, Status::success);
  ASSERT_EQ(remove("ball").status, Status::success);
  auto o = step_until(go, 20000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success) << o->message;
  EXPECT_EQ(o->value, "Arrived");
}

TEST_F(SimSpawnTest, DeleteRemovesTheEntityAndKeepsTheOthersState) {
  ASSERT_EQ(spawn("a", {2.0, 0.0, 0.5}).status, Status::success);
  ASSERT_EQ(spawn("b", {0.0, 2.0, 3.0}).status, Status::success);
  run_for(0.2);
  json objects = call("simulation", "get_scene_objects").value.value();
  const double b_height = objects["b"][1][2].get<double>();
  ASSERT_LT(b_height, 2.9);  // falling
  // no step while it compiles: however slow the worker (a sanitizer build), b is where it
  // was when the change was asked for
  auto answered = answer_without_stepping(rm_->call("simulation", "delete_entity", {"a"}));
  ASSERT_TRUE(answered.has_value());
  Outcome o = *answered;
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(o.value->at("model_generation"), 3);
  objects = call("simulation", "get_scene_objects").value.value();
  EXPECT_FALSE(objects.contains("a"));
  ASSERT_TRUE(objects.contains("b"));
  // b moved in MuJoCo's arrays, not in the world: still falling from where it was
  EXPECT_LT(objects["b"][1][2].get<double>(), b_height + 1e-9);
  EXPECT_GT(objects["b"][1][2].get<double>(), 0.2);
  EXPECT_EQ(sim_->model().entities().size(), 1u);
}

TEST_F(SimSpawnTest, RespawnAfterDeleteReusesTheName) {
  ASSERT_EQ(spawn("ball").status, Status::success);
  ASSERT_EQ(remove("ball").status, Status::success);
  EXPECT_EQ(spawn("ball").status, Status::success);
}

TEST_F(SimSpawnTest, SecondChangeWhileOneCompilesFails) {
  RequestId first = rm_->call("simulation", "spawn_entity", {"a", k_spawn_ball, {1.0, 0.0, 0.5}});
  RequestId second = rm_->call("simulation", "spawn_entity", {"b", k_spawn_ball, {2.0, 0.0, 0.5}});
  RequestId third = rm_->call("simulation", "delete_entity", {"a"});
  sim_->process_requests();
  for (RequestId id : {second, third}) {
    auto o = rm_->outcome(id);
    ASSERT_TRUE(o.has_value());
    EXPECT_EQ(o->status, Status::failed);
    EXPECT_EQ(o->failure, Failure::busy);
    EXPECT_NE(o->message.find("spawn_entity 'a' is compiling"), std::string::npos) << o->message;
  }
  EXPECT_EQ(finish(first).status, Status::success);
  EXPECT_EQ(sim_->model_generation(), 1u);
}

TEST_F(SimSpawnTest, CancelledSpawnLeavesTheWorldUnchanged) {
  remember_world();
  // the cancel goes with the request, in the same turn: a worker that compiled before a
  // later turn would have its model swapped in first (the turn's run_soon tasks come before
  // its requests), and the spawn would succeed (seen once on a loaded machine)
  RequestId id = rm_->call("simulation", "spawn_entity", {"ball", k_spawn_ball, {1.0, 0.0, 0.5}});
  rm_->cancel(id);
  Outcome o = finish(id);
  EXPECT_EQ(o.status, Status::preempted);
  // the worker finishes; its model is dropped, and the next change may start
  Outcome next = spawn("other");
  EXPECT_EQ(next.status, Status::success) << next.message;
  EXPECT_EQ(sim_->model().body_id("ball"), -1);
  EXPECT_EQ(sim_->model_generation(), generation_ + 1);
}

TEST_F(SimSpawnTest, TakenNameIsRefused) {
  remember_world();
  expect_refused(spawn("crate1"), "name", "is taken");
  ASSERT_EQ(spawn("ball").status, Status::success);
  remember_world();
  expect_refused(spawn("ball"), "name", "is taken");
}

TEST_F(SimSpawnTest, BadNamesArePoseAndMjcfAreRefused) {
  remember_world();
  expect_refused(spawn(""), "name", "expected 1 to 64");
  expect_refused(spawn("a b"), "name", "expected 1 to 64");
  expect_refused(spawn("body3"), "name", "unnamed bodies");
  expect_refused(spawn("ball", {1.0, 2.0}), "pose", "expected [x, y, z]");
  expect_refused(spawn("ball", {1.0, 2.0, 1e9}), "pose[2] (z)", "out of bounds");
  expect_refused(spawn("ball", {1.0, 2.0, 0.5, 0.0, 0.0, 0.0, 0.0}), "pose", "must not be zero");
  expect_refused(spawn("ball", {1.0, 2.0, "up"}), "pose", "");
  expect_refused(spawn("ball", {1.0, 2.0, 0.5}, "just text"), "mjcf", "expected MJCF text");
  expect_refused(spawn("ball", {1.0, 2.0, 0.5}, "<body><geom"), "mjcf", "not well-formed");
  expect_refused(
      spawn("ball", {1.0, 2.0, 0.5}, "<mujoco><option/><worldbody><body/></worldbody></mujoco>"),
      "mjcf", "<option> cannot be spawned");
}

TEST_F(SimSpawnTest, NonFiniteNumbersAreRefused) {
  remember_world();
  for (double bad : {std::nan(""), HUGE_VAL, -HUGE_VAL})
    expect_refused(spawn("ball", {1.0, bad, 0.5}), "pose[1] (y)", "out of bounds");
  expect_refused(spawn("ball", {1.0, 1.0, 0.5, std::nan(""), 0.0, 0.0, 1.0}), "pose[3]",
                 "out of bounds");
}

TEST_F(SimSpawnTest, FragmentThatDoesNotCompileGivesMujocosMessage) {
  remember_world();
  // a joint name the scene already uses: MuJoCo's "repeated name"
  expect_refused(spawn("ball", {1.0, 2.0, 0.5},
                       "<body><joint name='robot_root' type='free'/><geom size='.1'/></body>"),
                 "mjcf", "repeated name");
  expect_refused(spawn("ball", {1.0, 2.0, 0.5}, "<body><geom type='mesh' mesh='nope'/></body>"),
                 "mjcf", "does not compile");
  // and the simulation runs on
  run_for(0.1);
  EXPECT_TRUE(testing::state_is_finite(*sim_));
}

// issue #35 item 2: each of these went live and sent MuJoCo into a bad state on every step
// (the world reset each time), and some could not be deleted
TEST_F(SimSpawnTest, AFragmentThatWouldPoisonTheWorldIsRefusedAndNothingChanges) {
  remember_world();
  // refers to the scene's own joint
  expect_refused(spawn("thief", {0.0, -2.0, 0.5},
                       R"(<mujoco><worldbody><body><geom size=".1"/></body></worldbody>
      <actuator><motor name="thief_motor" joint="robot_left_wheel_joint" gear="1"/></actuator></mujoco>)"),
                 "mjcf", "refers to joint 'robot_left_wheel_joint', which is not the entity's");
  expect_refused(spawn("spy", {0.0, -2.0, 0.5},
                       R"(<mujoco><worldbody><body><geom size=".1"/></body></worldbody>
      <sensor><jointpos name="spy_pos" joint="robot_left_wheel_joint"/></sensor></mujoco>)"),
                 "mjcf", "which is not the entity's");
  // numbers no step survives
  expect_refused(spawn("biased", {0.0, -2.0, 0.5},
                       R"(<mujoco><worldbody><body><joint name="b_hinge" axis="0 0 1"/>
      <geom size=".1" mass="1"/></body></worldbody>
      <actuator><general name="b_motor" joint="b_hinge" biastype="affine" biasprm="0 1e300 0"/></actuator></mujoco>)"),
                 "mjcf", "actuator 'b_motor' has a bias parameter 1e+300");
  expect_refused(spawn("stiff", {0.0, -2.0, 0.5},
                       R"(<body><joint name="s_hinge" axis="0 0 1" stiffness="1e300"/>
      <geom size=".1" mass="1"/></body>)"),
                 "mjcf", "joint 's_hinge' has a stiffness 1e+300");
  expect_refused(
      spawn("sprung", {0.0, -2.0, 0.5}, R"(<body><joint name="r_slide" type="slide" stiffness="10"
      springref="1e11"/><geom size=".1" mass="1"/></body>)"),
      "mjcf", "joint 'r_slide' has a spring reference 1e+11");
  // sound numbers, yet it diverges from its first steps: the trial catches it
  expect_refused(spawn("wild", {0.0, -2.0, 0.5},
                       R"(<mujoco><worldbody><body><joint name="w_hinge" axis="0 0 1"/>
      <geom size=".1" mass="1e-9"/></body></worldbody>
      <actuator><general name="w_motor" joint="w_hinge" biastype="affine" biasprm="1e9 0 0"/></actuator></mujoco>)"),
                 "mjcf", "makes the model diverge");
  run_for(0.1);
  EXPECT_EQ(sim_->statistics().bad_states, 0u);
}

TEST_F(SimSpawnTest, ASelfContainedRobotWithActuatorSensorTendonAndEqualityCanBeDeleted) {
  Outcome o = spawn("arm", {0.0, -2.0, 0.5}, R"(<mujoco>
      <worldbody><body><joint name="arm_j1" axis="0 0 1"/><geom name="arm_g1" size=".1" mass="1"/><site name="arm_s1"/>
        <body pos=".3 0 0"><joint name="arm_j2" axis="0 0 1"/><geom size=".05" mass="1"/><site name="arm_s2"/></body>
      </body></worldbody>
      <tendon><fixed name="arm_t"><joint joint="arm_j1" coef="1"/><joint joint="arm_j2" coef="-1"/></fixed></tendon>
      <equality><joint name="arm_eq" joint1="arm_j1" joint2="arm_j2"/></equality>
      <actuator><motor name="arm_m" joint="arm_j1"/><motor name="arm_mt" tendon="arm_t"/></actuator>
      <sensor><jointpos name="arm_p" joint="arm_j1"/><tendonpos name="arm_tp" tendon="arm_t"/></sensor>
    </mujoco>)");
  ASSERT_EQ(o.status, Status::success) << o.message;
  ASSERT_EQ(spawn("ball").status, Status::success);
  run_for(0.1);
  Outcome deleted = remove("arm");
  ASSERT_EQ(deleted.status, Status::success) << deleted.message;
  EXPECT_EQ(sim_->model().actuator_id("arm_m"), -1);
  EXPECT_EQ(sim_->model().actuator_id("robot_left_motor"), 0);
  run_for(0.2);
  EXPECT_TRUE(testing::state_is_finite(*sim_));
  EXPECT_EQ(sim_->statistics().bad_states, 0u);
  EXPECT_EQ(remove("ball").status, Status::success);
}

TEST_F(SimSpawnTest, DeleteOfUnknownOrUsedBodyIsRefused) {
  remember_world();
  expect_refused(remove("ghost"), "name",
                 "no body or entity named 'ghost' (no entity has been spawned)");
  expect_refused(remove("robot_left_wheel"), "name", "is part of robot 'robot''s body 'robot'");
  ASSERT_EQ(spawn("ball").status, Status::success);
  remember_world();
  expect_refused(remove("ghost"), "name", "(spawned: 'ball')");
}

TEST_F(SimSpawnTest, MujocoFragmentWithAnActuatorCanBeDriven) {
  Outcome o = spawn("spinner", {0.0, -2.0, 0.5}, R"(<mujoco>
      <worldbody><body><joint name="spinner_hinge" type="hinge" axis="0 0 1"/>
        <geom type="box" size=".3 .05 .05" mass="1"/></body></worldbody>
      <actuator><velocity name="spinner_motor" joint="spinner_hinge" kv="5"/></actuator>
    </mujoco>)");
  ASSERT_EQ(o.status, Status::success) << o.message;
  // the scene's actuators keep their ids; the entity's comes after them
  EXPECT_EQ(sim_->model().actuator_id("robot_left_motor"), 0);
  const int motor = sim_->model().actuator_id("spinner_motor");
  EXPECT_EQ(motor, sim_->m()->nu - 1);
  sim_->d()->ctrl[motor] = 2.0;
  run_for(0.5);
  EXPECT_NEAR(sim_->d()->qvel[sim_->m()->jnt_dofadr[sim_->model().joint_id("spinner_hinge")]], 2.0,
              0.1);
}

// A state saved before a spawn and a delete is restored after them, and stepping on from it
// gives the same bits as stepping on from it before the model changed (issue #36).
TEST_F(SimSpawnTest, AStateSavedBeforeASpawnAndADeleteIsRestoredExactly) {
  auto qpos = [&] { return std::vector<mjtNum>(sim_->d()->qpos, sim_->d()->qpos + sim_->m()->nq); };
  ASSERT_EQ(call("robot.motion", "set_speed", {0.7, 0.4}).status, Status::success);
  run_for(0.3);
  const json handle = call("simulation", "save_state").value.value_or(json());
  // stepping on from the saved state, on the model it was saved from
  ASSERT_EQ(call("simulation", "restore_state", {handle}).status, Status::success);
  ASSERT_EQ(call("robot.motion", "set_speed", {0.7, 0.4}).status, Status::success);
  run_for(0.5);
  const auto expected = qpos();

  ASSERT_EQ(spawn("ball").status, Status::success);
  run_for(0.2);
  ASSERT_EQ(remove("ball").status, Status::success);
  Outcome o = call("simulation", "restore_state", {handle});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ((*o.value)["exact"], false);
  EXPECT_TRUE((*o.value)["missing"]["bodies"].empty()) << o.value->dump();
  EXPECT_TRUE((*o.value)["kept"]["bodies"].empty()) << o.value->dump();
  ASSERT_EQ(call("robot.motion", "set_speed", {0.7, 0.4}).status, Status::success);
  run_for(0.5);
  EXPECT_TRUE(testing::same_bits(qpos(), expected));
}

// What the saved state does not know (an entity spawned since) stays as it is and is
// reported kept; what it knew that is gone (a body deleted since) is reported missing.
TEST_F(SimSpawnTest, RestoringAcrossAnEditReportsWhatIsMissingAndWhatIsKept) {
  const json handle = call("simulation", "save_state").value.value_or(json());
  ASSERT_EQ(spawn("ball", {1.0, 1.0, 3.0}).status, Status::success);
  ASSERT_EQ(remove("crate1").status, Status::success);
  run_for(0.2);
  const int ball_z =
      sim_->m()->jnt_qposadr[sim_->m()->body_jntadr[sim_->model().body_id("ball")]] + 2;
  const double z = sim_->d()->qpos[ball_z];
  ASSERT_LT(z, 3.0);  // it fell
  Outcome o = call("simulation", "restore_state", {handle});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ((*o.value)["missing"]["bodies"], json::array({"crate1"})) << o.value->dump();
  EXPECT_EQ((*o.value)["kept"]["bodies"], json::array({"ball"})) << o.value->dump();
  EXPECT_EQ((*o.value)["kept"]["joints"], json::array({"ball/0"})) << o.value->dump();
  EXPECT_EQ(sim_->d()->qpos[ball_z], z);
  EXPECT_EQ(sim_->sim_time(), 0.0);
}

// A robot section needs the host's factory (the gateway's: component types, mapping); a
// simulation without one says so, and a section that is not an object is refused.
TEST_F(SimSpawnTest, ARobotSectionWithoutAFactoryOrNotAnObjectIsRefused) {
  remember_world();
  expect_refused(finish(rm_->call("simulation", "spawn_entity",
                                  {"arm", k_spawn_ball, {1.0, 1.0, 0.5}, {{"type", "robot"}}})),
                 "robot", "builds no robots at run time");
  expect_refused(finish(rm_->call("simulation", "spawn_entity",
                                  {"arm", k_spawn_ball, {1.0, 1.0, 0.5}, "robot"})),
                 "robot", "expected an object");
  // {} is a plain body, as without the parameter
  EXPECT_EQ(finish(rm_->call("simulation", "spawn_entity",
                             {"arm", k_spawn_ball, {1.0, 1.0, 0.5}, json::object()}))
                .status,
            Status::success);
}

// A spawn and a delete change the world under every client: simulation.events says so, with
// the name, the new model generation and who asked (the swap runs outside the request; it
// said nothing before).
TEST_F(SimSpawnTest, SpawnAndDeleteAreAnnouncedOnTheEventStream) {
  sim_->streams().add(*sim_->find("simulation.events")->component, "events", {"test"});
  auto events = sim_->streams().subscribe("simulation.events", "test", {64, "test", {}});
  ASSERT_EQ(spawn("ball").status, Status::success);
  ASSERT_EQ(remove("robot").status, Status::success);
  std::vector<SamplePtr> samples;
  events->take(samples);
  ASSERT_EQ(samples.size(), 2u);
  const json spawned = samples[0]->data(), deleted = samples[1]->data();
  EXPECT_EQ(spawned["event"], "spawned");
  EXPECT_EQ(spawned["name"], "ball");
  EXPECT_EQ(spawned["model_generation"], 1);
  EXPECT_EQ(spawned["robot"], false);
  EXPECT_EQ(spawned["by"], "test");
  EXPECT_EQ(deleted["event"], "deleted");
  EXPECT_EQ(deleted["name"], "robot");
  EXPECT_EQ(deleted["model_generation"], 2);
  EXPECT_EQ(deleted["robots"], json::array({"robot"}));
  EXPECT_EQ(deleted["by"], "test");
}

TEST_F(SimSpawnTest, ServicesAreListed) {
  json services = call("simulation", "list_services").value.value();
  int found = 0;
  for (const auto& s : services)
    if (s["component"] == "simulation" &&
        (s["name"] == "spawn_entity" || s["name"] == "delete_entity"))
      ++found;
  EXPECT_EQ(found, 2);
}

// Fragment files: only under the directories SimulationOptions::spawn_allowed_dirs names
// (the config's spawn.allowed_dirs).
class SimSpawnFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = std::filesystem::temp_directory_path() /
            ("simgate_spawn_files_" + std::to_string(::getpid()));
    std::filesystem::create_directories(root_ / "allowed");
    std::ofstream(root_ / "allowed" / "ball.xml") << k_spawn_ball;
    std::ofstream(root_ / "allowed" / "broken.xml")
        << "<body><geom type='sphere' size='0.1'></body";
    std::ofstream(root_ / "outside.xml") << k_spawn_ball;
    std::filesystem::create_symlink(root_ / "outside.xml", root_ / "allowed" / "link.xml");
    SimulationOptions options{std::nullopt, 0.0};
    options.spawn_allowed_dirs = {std::filesystem::canonical(root_ / "allowed").string()};
    sim_ = std::make_unique<Simulation>(Model::load_file(testing::demo_scene()), options);
    add_world_components(*sim_);
    rm_ = std::make_shared<testing::RecordingManager>();
    rm_->register_component(*sim_->find("simulation")->component);
    sim_->add_request_manager(rm_, "test");
  }
  void TearDown() override {
    rm_.reset();
    sim_.reset();
    std::filesystem::remove_all(root_);
  }
  Outcome spawn(const std::string& name, const std::string& file) {
    RequestId id = rm_->call("simulation", "spawn_entity", {name, file, {1.0, 1.0, 0.5}});
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < deadline) {
      sim_->process_requests();
      if (auto o = rm_->outcome(id)) return *o;
      sim_->step();
    }
    return Outcome::failed(Failure::internal, "no answer");
  }

  std::filesystem::path root_;
  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<testing::RecordingManager> rm_;
};

TEST_F(SimSpawnFileTest, AFileUnderAnAllowedDirectorySpawns) {
  Outcome relative = spawn("a", "ball.xml");
  EXPECT_EQ(relative.status, Status::success) << relative.message;
  Outcome absolute = spawn("b", (root_ / "allowed" / "ball.xml").string());
  EXPECT_EQ(absolute.status, Status::success) << absolute.message;
  EXPECT_EQ(sim_->model().entities().size(), 2u);
}

// the worker reads the file: what is wrong in it comes back as the request's refusal, and
// the world is unchanged
TEST_F(SimSpawnFileTest, AFileThatHoldsNoEntityIsRefusedNamingMjcf) {
  Outcome o = spawn("a", "broken.xml");
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_EQ(o.failure, Failure::bad_arguments) << o.message;
  EXPECT_EQ(o.data.value("parameter", ""), "mjcf") << o.message;
  EXPECT_EQ(o.message.rfind("mjcf: ", 0), 0u) << o.message;
  EXPECT_EQ(sim_->model_generation(), 0u);
  EXPECT_EQ(spawn("b", "ball.xml").status, Status::success) << "the next change starts";
}

TEST_F(SimSpawnFileTest, AnythingElseIsRefusedAsIfMissing) {
  for (const std::string& path :
       {std::string("../outside.xml"), (root_ / "outside.xml").string(), std::string("link.xml"),
        std::string("missing.xml"), std::string("/etc/hostname")}) {
    Outcome o = spawn("a", path);
    EXPECT_EQ(o.status, Status::failed) << path;
    EXPECT_EQ(o.failure, Failure::bad_arguments) << path;
    EXPECT_NE(o.message.find("is neither MJCF or URDF text nor a fragment file under the "
                             "directories the config allows"),
              std::string::npos)
        << o.message;
  }
  EXPECT_EQ(sim_->model_generation(), 0u);
}

TEST_F(SimSpawnTest, WithoutAllowedDirectoriesOnlyInlineMjcfIsAccepted) {
  remember_world();
  expect_refused(spawn("ball", {1.0, 1.0, 0.5}, "ball.xml"), "mjcf", "it allows none");
}

}  // namespace
}  // namespace simgate::sim
