// The built-in components' data streams in a real simulation: the simulation publishes
// after its steps (samples are the components' get_local_data, stamped with the state's
// time), a new subscriber of a paused simulation gets the current state, and the
// actuators' commands act as their services do (with their bounds), refusals named.
#include <gtest/gtest.h>

#include "armature_fixture.h"
#include "sim_fixture.h"

namespace simgate::sim::testing {
namespace {

class DemoStreams : public DemoSim {
 protected:
  void SetUp() override {
    DemoSim::SetUp();
    for (const char* name : {"robot.motion", "robot.waypoint", "robot.teleport", "robot.pose"})
      sim_->streams().add(*sim_->find(name)->component, sim_->find(name)->type, {"test"}, 100);
  }
  std::vector<SamplePtr> take(StreamSubscription& s) {
    std::vector<SamplePtr> out;
    s.take(out);
    return out;
  }
  PublishResult publish(const std::string& component, json command) {
    return sim_->streams().publish(component, "test", std::move(command));
  }
};

TEST_F(DemoStreams, PoseSamplesAreItsLocalDataAtTheFrequencyAfterSteps) {
  auto sub = sim_->streams().subscribe("robot.pose", "test", {64, "test", {}});
  ASSERT_TRUE(sub);
  run_for(0.1);  // 50 steps of 2 ms; 100 Hz: every fifth step, plus the first at once
  auto samples = take(*sub);
  ASSERT_EQ(samples.size(), 10u);
  for (std::size_t i = 1; i < samples.size(); ++i)
    EXPECT_NEAR(samples[i]->time() - samples[i - 1]->time(), 0.01, 1e-9);
  json p = pose();
  for (auto it = p.begin(); it != p.end(); ++it)
    EXPECT_TRUE(samples.back()->data().contains(it.key())) << it.key();
  EXPECT_EQ(samples.back()->data()["timestamp"], samples.back()->time());
  EXPECT_EQ(sim_->streams().total_samples(), 10u);
}

TEST_F(DemoStreams, APausedSimulationGivesANewSubscriberTheCurrentState) {
  sim_->set_paused(true);
  auto sub = sim_->streams().subscribe("robot.pose", "test", {});
  EXPECT_TRUE(sim_->streams().turn_wanted());
  sim_->process_requests();  // a turn without a step
  auto samples = take(*sub);
  ASSERT_EQ(samples.size(), 1u);
  EXPECT_EQ(samples[0]->data(), pose());
  sim_->process_requests();
  EXPECT_TRUE(take(*sub).empty());  // no step, no more
}

TEST_F(DemoStreams, MotionCommandsDriveTheRobotAsSetSpeedDoes) {
  PublishResult r = publish("robot.motion", {{"v", 1.0}, {"w", 0.0}});
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.applied);  // nobody held the lock
  const double x0 = pose()["x"];
  run_for(1.0);
  EXPECT_GT(pose()["x"].get<double>(), x0 + 0.5);
  // the bounds of set_speed apply; keys are checked
  r = publish("robot.motion", {{"v", 1e9}, {"w", 0.0}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("v"), std::string::npos) << r.error;
  r = publish("robot.motion", {{"v", 1.0}});
  EXPECT_EQ(r.error, "the command has no 'w'");
  r = publish("robot.motion", {{"v", "fast"}, {"w", 0.0}});
  EXPECT_EQ(r.error, "v: expected a number, found string \"fast\"");
  EXPECT_TRUE(publish("robot.motion", {{"v", 0.0}, {"w", 0.0}, {"timestamp", 3.0}})
                  .ok);  // a sample's timestamp
}

TEST_F(DemoStreams, TeleportCommandsPlaceTheRobotAbsolutely) {
  ASSERT_TRUE(publish("robot.teleport", {{"x", 1.5}, {"y", -0.5}, {"yaw", 1.0}}).ok);
  json p = pose();
  EXPECT_NEAR(p["x"].get<double>(), 1.5, 1e-9);
  EXPECT_NEAR(p["y"].get<double>(), -0.5, 1e-9);
  EXPECT_NEAR(p["yaw"].get<double>(), 1.0, 1e-9);
  const double z = p["z"];
  ASSERT_TRUE(publish("robot.teleport", {{"x", 1.5}, {"y", -0.5}}).ok);  // z kept, angles 0
  EXPECT_NEAR(pose()["z"].get<double>(), z, 1e-9);
  EXPECT_NEAR(pose()["yaw"].get<double>(), 0, 1e-9);
  EXPECT_FALSE(publish("robot.teleport", {{"x", 1e12}}).ok);
  PublishResult r = publish("robot.teleport", {{"X", 1.0}});
  EXPECT_EQ(r.error,
            "the command has an unknown key 'X' (expected x, y, z, roll, pitch, yaw) (did you mean "
            "'x'?)");
}

TEST_F(DemoStreams, WaypointCommandsSetTheDestination) {
  ASSERT_TRUE(publish("robot.waypoint", {{"x", 2.0}, {"y", 0.0}, {"speed", 0.5}}).ok);
  EXPECT_EQ(call("robot.waypoint", "get_status").value, json("Transit"));
  EXPECT_EQ(call("robot.waypoint", "get_properties").value.value()["properties"]["target"],
            json({2.0, 0.0, 0.0}));
}

TEST_F(DemoStreams, ACommandThatWaitsForTheLockIsAppliedOnTheNextTurn) {
  sim_->gate()->lock();
  PublishResult r;
  std::thread transport([&] { r = publish("robot.motion", {{"v", 0.5}, {"w", 0.25}}); });
  transport.join();
  sim_->gate()->unlock();
  EXPECT_TRUE(r.ok);
  EXPECT_FALSE(r.applied);
  sim_->process_requests();
  auto* drive = dynamic_cast<DifferentialDrive*>(sim_->find("robot")->component.get());
  ASSERT_TRUE(drive);
  EXPECT_DOUBLE_EQ(drive->linear_velocity(), 0.5);
  EXPECT_DOUBLE_EQ(drive->angular_velocity(), 0.25);
}

TEST_F(DemoStreams, StatisticsCountWhatHappened) {
  auto sub = sim_->streams().subscribe("robot.pose", "test", {2, "slow", {}});
  run_for(0.1);
  publish("robot.motion", {{"v", 0.1}, {"w", 0.0}});
  publish("robot.motion", {{"oops", 1}});
  Outcome o = call("simulation", "get_stream_statistics");
  ASSERT_TRUE(o.value);
  json stats = *o.value;
  ASSERT_EQ(stats.size(), 4u) << stats.dump();
  json pose_stats, motion_stats;
  for (const auto& s : stats) {
    if (s["component"] == "robot.pose") pose_stats = s;
    if (s["component"] == "robot.motion") motion_stats = s;
  }
  EXPECT_EQ(pose_stats["samples"], 10);
  EXPECT_EQ(pose_stats["dropped"], 8);  // it kept 2
  EXPECT_EQ(pose_stats["subscribers"], 1);
  EXPECT_EQ(pose_stats["frequency"], 100);
  EXPECT_EQ(motion_stats["commands"], 1);
  EXPECT_EQ(motion_stats["refused"], 1);
  json time_stats = call("time", "statistics").value.value();
  EXPECT_EQ(time_stats["stream_samples"], 10);
  EXPECT_EQ(time_stats["stream_samples_dropped"], 8);
}

TEST_F(DemoStreams, DetailsListsEachStreamInterface) {
  json details = call("simulation", "details").value.value();
  json components = details["robots"][0]["components"];
  EXPECT_EQ(components["robot.pose"]["stream_interfaces"],
            json::array({json::array({"simgate.test.publisher", "OUT"})}));
  EXPECT_EQ(components["robot.motion"]["stream_interfaces"],
            json::array({json::array({"simgate.test.reader", "IN"})}));
}

class ArmatureStreams : public ArmatureSim {};

TEST_F(ArmatureStreams, JointCommandsSetEachJointInItsUnitAndJointStateSamplesFollow) {
  build_arm();
  sim_->streams().add(*sim_->find("arm.arm")->component, "armature", {"test"});
  sim_->streams().add(*sim_->find("arm.pose")->component, "armature_pose", {"test"});
  PublishResult r =
      sim_->streams().publish("arm.arm", "test", {{"shoulder", 0.5}, {"slider", 0.05}});
  ASSERT_TRUE(r.ok) << r.error;
  auto sub = sim_->streams().subscribe("arm.pose", "test", {});
  sim_->process_requests();
  std::vector<SamplePtr> samples;
  sub->take(samples);
  ASSERT_EQ(samples.size(), 1u);
  EXPECT_NEAR(samples[0]->data()["shoulder"].get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(samples[0]->data()["slider"].get<double>(), 0.05, 1e-9);
  // out of a joint's range, or a joint that is not there: refused, nothing moved
  r = sim_->streams().publish("arm.arm", "test", {{"slider", 0.5}});
  EXPECT_FALSE(r.ok);
  r = sim_->streams().publish("arm.arm", "test", {{"wrist", 0.5}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("wrist"), std::string::npos) << r.error;
}

}  // namespace
}  // namespace simgate::sim::testing
