// Progress reports of the built-in async services (issue #20), for calls that asked for
// them (Call::progress): waypoint goto reports the distance left, armature motions the
// points reached and the time left, simulation step the steps done, time sleep the time
// left. A call that did not ask gets none.
#include "armature_fixture.h"
#include "sim_fixture.h"

namespace simgate::sim {
namespace {

class WaypointProgressTest : public testing::DemoSim {
 protected:
  void SetUp() override {
    DemoSim::SetUp();
    rm_->set_progress_interval(std::chrono::nanoseconds(0));  // every step's report
  }
};

TEST_F(WaypointProgressTest, GotoReportsTheDistanceLeftShrinkingThenArrives) {
  RequestId id = rm_->call_with_progress("robot.waypoint", "goto", {2.0, 0.0, 0.0, 0.2, 1.0});
  auto done = step_until(id, 20000);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  const std::vector<json> reports = rm_->progress(id);
  ASSERT_GT(reports.size(), 10u);
  const double first = reports.front()["distance_left"].get<double>();
  const double last = reports.back()["distance_left"].get<double>();
  EXPECT_NEAR(first, 2.0, 0.05);
  EXPECT_LT(last, first);
  EXPECT_GT(last, 0.2);  // reports come while it is under way: the arrival is the outcome
}

TEST_F(WaypointProgressTest, AGotoWhoseClientDidNotAskReportsNothing) {
  RequestId id = rm_->call("robot.waypoint", "goto", json::array({1.0, 0.0, 0.0, 0.2, 1.0}));
  ASSERT_TRUE(step_until(id, 20000).has_value());
  EXPECT_TRUE(rm_->progress(id).empty());
}

TEST_F(WaypointProgressTest, StepReportsTheStepsDoneThenEnds) {
  ASSERT_EQ(call("simulation", "pause").status, Status::success);
  RequestId id = rm_->call_with_progress("simulation", "step", {5});
  sim_->process_requests();  // the caller's thread takes the steps itself
  auto done = step_until(id, 10);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  std::vector<json> reports = rm_->progress(id);
  ASSERT_EQ(reports.size(), 5u);
  for (std::size_t i = 0; i < reports.size(); ++i) {
    EXPECT_EQ(reports[i]["steps_done"], i);  // reported as each step begins
    EXPECT_EQ(reports[i]["steps_requested"], 5);
  }
}

TEST_F(WaypointProgressTest, SleepReportsTheTimeLeft) {
  RequestId id = rm_->call_with_progress("time", "sleep", {0.1});
  auto done = step_until(id, 200);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  std::vector<json> reports = rm_->progress(id);
  ASSERT_GT(reports.size(), 10u);
  EXPECT_NEAR(reports.front()["time_left"].get<double>(), 0.1, 2 * sim_->timestep());
  EXPECT_LT(reports.back()["time_left"].get<double>(), reports.front()["time_left"].get<double>());
  EXPECT_GT(reports.back()["time_left"].get<double>(), 0.0);
}

class ArmatureProgressTest : public testing::ArmatureSim {};

TEST_F(ArmatureProgressTest, ATrajectoryReportsThePointsReachedAndTheTimeLeft) {
  build_arm();
  rm_->set_progress_interval(std::chrono::nanoseconds(0));
  json trajectory = {{"points",
                      {{{"positions", {0.4, -0.4, 0.05}}, {"time_from_start", 1.0}},
                       {{"positions", {0.8, 0.0, 0.1}}, {"time_from_start", 2.0}}}}};
  RequestId id = rm_->call_with_progress("arm.arm", "trajectory", {trajectory});
  auto done = run_until_answered(id, 5.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  const std::vector<json> reports = rm_->progress(id);
  ASSERT_GT(reports.size(), 100u);
  EXPECT_EQ(reports.front()["points"], 2);
  EXPECT_EQ(reports.front()["points_reached"], 0);
  EXPECT_NEAR(reports.front()["time_left"].get<double>(), 2.0, 0.01);
  bool saw_one = false;
  for (const json& r : reports) saw_one = saw_one || r["points_reached"] == 1;
  EXPECT_TRUE(saw_one);
  EXPECT_EQ(reports.back()["points_reached"], 2);
  EXPECT_DOUBLE_EQ(reports.back()["time_left"].get<double>(), 0.0);
}

}  // namespace
}  // namespace simgate::sim
