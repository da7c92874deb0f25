// SimExample: the component from docs/writing-a-component.md, compiled and tested so the
// documentation cannot rot. An odometer measures the distance its robot travelled:
// sync `get_distance`, async `wait_distance d` (completes once the robot has travelled d
// more metres; interruptible).
#include "sim_fixture.h"

// ---- the example, as in the doc ----------------------------------------------------------
namespace example {

using namespace simgate;
using namespace simgate::sim;

class Odometer : public SimComponent {
 public:
  explicit Odometer(ComponentContext& c) : SimComponent(c.name(), c.sim()), robot_(c.robot()) {
    // options are read (and checked) here; unknown keys are reported by the registry
    min_step_ = c.options().get_number("min_step", 1e-4, 0.0, 1.0);
    last_ = robot_.position();
    add_service("get_distance", &Odometer::get_distance).doc("Metres travelled since start or reset");
    add_async_service("wait_distance", &Odometer::wait_distance, {"distance"})
        .interruptible()
        .doc("Completes once the robot has travelled `distance` more metres");
  }

  double get_distance() const { return total_; }

  void wait_distance(double distance) {
    if (!(distance > 0)) throw ServiceError("distance must be positive");
    goal_ = total_ + distance;
  }

  // every step, on the simulation thread
  void default_action() override {
    Eigen::Vector3d p = robot_.position();
    double step = (p - last_).head<2>().norm();
    if (step >= min_step_) {  // ignore contact jitter
      total_ += step;
      last_ = p;
    }
    if (has_running_request() && total_ >= goal_) completed(Status::success, total_);
  }

  void on_reset() override {
    total_ = 0;
    last_ = robot_.position();
  }

 private:
  Robot& robot_;            // whose distance is measured
  double min_step_;         // metres; smaller moves are ignored
  Eigen::Vector3d last_;    // position at the last counted move
  double total_ = 0;        // metres travelled
  double goal_ = 0;         // total_ at which wait_distance completes
};

}  // namespace example

// ---- its tests ---------------------------------------------------------------------------
namespace simgate::sim {
namespace {

class SimExampleTest : public testing::DemoSim {
 protected:
  void SetUp() override {
    DemoSim::SetUp();
    ComponentRegistry registry;
    registry.add<example::Odometer>("odometer", Kind::component, "distance travelled");
    auto* robot = static_cast<Robot*>(sim_->find("robot")->component.get());
    auto odometer = registry.create(Kind::component, {"robot.odometer", "odometer", "robot", "test"}, json::object(),
                                    *sim_, robot);
    rm_->register_component(*odometer);
    sim_->add_component(std::move(odometer), "odometer", "robot");
  }
};

TEST_F(SimExampleTest, SyncServiceReportsTheDistance) {
  EXPECT_EQ(call("robot.odometer", "get_distance").status, Status::success);
  call("robot.motion", "set_speed", {1.0, 0.0});
  run_for(1.0);
  EXPECT_GT(call("robot.odometer", "get_distance").value->get<double>(), 0.5);
}

TEST_F(SimExampleTest, AsyncServiceCompletesAfterTheDistance) {
  call("robot.motion", "set_speed", {1.0, 0.0});
  RequestId id = rm_->call("robot.odometer", "wait_distance", {1.0});
  auto o = step_until(id, 2000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_GE(o->value->get<double>(), 1.0);
}

TEST_F(SimExampleTest, AsyncServiceIsInterruptible) {
  RequestId first = rm_->call("robot.odometer", "wait_distance", {100.0});
  sim_->process_requests();
  RequestId second = rm_->call("robot.odometer", "wait_distance", {1.0});
  sim_->process_requests();
  EXPECT_EQ(rm_->outcome(first)->status, Status::preempted);
  EXPECT_FALSE(rm_->outcome(second).has_value());
}

TEST_F(SimExampleTest, BadArgumentFails) {
  EXPECT_EQ(call("robot.odometer", "wait_distance", {-1.0}).value, json("distance must be positive"));
}

}  // namespace
}  // namespace simgate::sim
