// SimCommunication: the `communication` pseudo-component (MORSE's distance_and_view) on
// the demo scene: the robot, the human, and a crate moved between them.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "sim_fixture.h"

namespace simgate::sim::testing {
namespace {

using ::testing::HasSubstr;

class SimCommunicationTest : public DemoSim {
 protected:
  void place(const std::string& body, json position) {
    ASSERT_EQ(call("simulation", "set_object_position", {body, std::move(position)}).status,
              Status::success);
  }
  json distance_and_view(const std::string& a, const std::string& b) {
    Outcome o = call("communication", "distance_and_view", {a, b});
    EXPECT_EQ(o.status, Status::success) << o.message;
    return o.value.value_or(json());
  }
};

TEST_F(SimCommunicationTest, GivesTheDistanceBetweenTheRootsAndSeesAcrossAnEmptyFloor) {
  json r = distance_and_view("robot", "human");
  // robot at (0, 0, 0.1), human at (-2, 2, 0.05): demo.xml
  EXPECT_NEAR(r[0].get<double>(), std::sqrt(8 + 0.05 * 0.05), 1e-9);
  EXPECT_EQ(r[1], true);
  EXPECT_EQ(distance_and_view("human", "robot"), r);
  EXPECT_EQ(distance_and_view("robot", "robot"), json({0.0, true}));
}

TEST_F(SimCommunicationTest, ACrateBetweenThemHidesOneFromTheOther) {
  place("crate1", {-1.0, 1.0, 0.2});
  json r = distance_and_view("robot", "human");
  EXPECT_EQ(r[1], false);
  EXPECT_EQ(distance_and_view("human", "robot")[1], false);
  // moved aside: seen again
  place("crate1", {-1.0, -1.0, 0.2});
  EXPECT_EQ(distance_and_view("robot", "human")[1], true);
}

TEST_F(SimCommunicationTest, ARobotsOwnBodiesDoNotHideIt) {
  // the human straight ahead of the robot's left wheel: the line from the robot's root
  // crosses that wheel (a body of its own other than the root, which mj_ray alone would
  // count as an obstacle) and then the human's own geoms
  place("human", {0.1, 3.0, 0.1});
  const int wheel = sim_->model().body_id("robot_left_wheel");
  const Eigen::Vector3d from = body_position(*sim_, sim_->model().body_id("robot"));
  Eigen::Vector3d segment = body_position(*sim_, sim_->model().body_id("human")) - from;
  int geom = -1;
  ASSERT_GE(mj_ray(sim_->m(), sim_->d(), from.data(), segment.data(), nullptr, 1,
                   sim_->model().body_id("robot"), &geom, nullptr),
            0);
  ASSERT_EQ(sim_->m()->geom_bodyid[geom], wheel) << "the scene no longer tests what it should";
  EXPECT_EQ(distance_and_view("robot", "human")[1], true);
  EXPECT_EQ(distance_and_view("human", "robot")[1], true);
  // and a crate in the way still hides it
  place("crate2", {0.05, 1.5, 0.2});
  EXPECT_EQ(distance_and_view("robot", "human")[1], false);
}

TEST_F(SimCommunicationTest, UnknownRobotsAndMissingArgumentsAreRefused) {
  Outcome unknown = call("communication", "distance_and_view", {"robot", "nobody"});
  EXPECT_EQ(unknown.status, Status::failed);
  EXPECT_EQ(unknown.message, "nobody does not exist in the simulation ");  // MORSE's text
  EXPECT_EQ(unknown.data["parameter"], "robot2");
  EXPECT_EQ(unknown.data["choices"], json({"robot", "human"}));
  // a body that is not a robot, and a component that is not one either
  EXPECT_EQ(call("communication", "distance_and_view", {"crate1", "robot"}).message,
            "crate1 does not exist in the simulation ");
  EXPECT_EQ(call("communication", "distance_and_view", {"robot.motion", "robot"}).status,
            Status::failed);
  Outcome none = call("communication", "distance_and_view", json::array());
  EXPECT_EQ(none.status, Status::failed);
  EXPECT_THAT(none.message,
              HasSubstr("parameters expected for service communication.distance_and_view!"));
}

}  // namespace
}  // namespace simgate::sim::testing
