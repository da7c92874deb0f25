// SimSupervision: the `simulation` and `time` pseudo-components.
#include <map>
#include <set>

#include "sim_fixture.h"
#include "simgate/sim/supervision.h"

namespace simgate::sim {
namespace {

using testing::DemoSim;
using ::testing::HasSubstr;

class SimSupervisionTest : public DemoSim {};

TEST_F(SimSupervisionTest, ListRobots) {
  EXPECT_EQ(call("simulation", "list_robots").value, json({"robot", "human"}));
}

TEST_F(SimSupervisionTest, DetailsHasTheShapePymorseReads) {
  json d = call("simulation", "details").value.value_or(json());
  ASSERT_TRUE(d.contains("robots"));
  ASSERT_EQ(d["robots"].size(), 2u);
  json robot = d["robots"][0];
  EXPECT_EQ(robot["name"], "robot");
  ASSERT_TRUE(robot["components"].is_object());
  json waypoint = robot["components"]["robot.waypoint"];
  EXPECT_EQ(waypoint["type"], "waypoint");
  EXPECT_EQ(waypoint["service_interfaces"], json({"test"}));
  EXPECT_NE(std::find(waypoint["services"].begin(), waypoint["services"].end(), json("goto")),
            waypoint["services"].end());
  EXPECT_FALSE(waypoint.contains("stream_interfaces"));  // pymorse would ask for stream ports
  json human = d["robots"][1];
  EXPECT_EQ(human["services"],
            json({"move", "get_properties", "set_property", "get_configurations"}));
  EXPECT_EQ(human["services_interfaces"], json({"test"}));  // MORSE's robot-level spelling
}

TEST_F(SimSupervisionTest, DetailsOmitsServicesOfComponentsNoTransportServes) {
  sim_->find("robot.teleport")->interfaces.clear();
  json d = call("simulation", "details").value.value_or(json());
  EXPECT_FALSE(d["robots"][0]["components"]["robot.teleport"].contains("services"));
}

TEST_F(SimSupervisionTest, ListServicesGivesEveryServiceWithItsParameters) {
  json list = call("simulation", "list_services").value.value_or(json());
  bool found = false;
  for (const auto& s : list)
    if (s["component"] == "robot.waypoint" && s["name"] == "goto") {
      found = true;
      EXPECT_EQ(s["async"], true);
      ASSERT_EQ(s["params"].size(), 5u);
      EXPECT_EQ(s["params"][3]["name"], "tolerance");
      EXPECT_EQ(s["params"][3]["default"], 0.5);
      EXPECT_EQ(s["transports"], json({"test"}));
    }
  EXPECT_TRUE(found);
}

TEST_F(SimSupervisionTest, ResetObjectsRestoresInitialPoses) {
  call("robot.teleport", "translate", {3.0, 0.0, 0.0});
  call("robot.motion", "set_speed", {1.0, 0.0});
  EXPECT_EQ(call("simulation", "reset_objects").value,
            json("Objects restored to initial position"));
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 1e-9);
  run_for(0.5);
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 0.01);  // the command was dropped too
}

TEST_F(SimSupervisionTest, DeactivatedComponentSkipsItsDefaultAction) {
  EXPECT_EQ(call("simulation", "deactivate", {"robot.waypoint"}).status, Status::success);
  call("robot.waypoint", "setdest", {3.0, 0.0, 0.0});
  run_for(1.0);
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 0.01);  // no steering, no driving
  EXPECT_EQ(call("simulation", "activate", {"robot.waypoint"}).status, Status::success);
  run_for(1.0);
  EXPECT_GT(pose()["x"].get<double>(), 0.2);
}

TEST_F(SimSupervisionTest, ActivatingAnUnknownComponentFails) {
  Outcome o = call("simulation", "activate", {"robot.nope"});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(o.message, HasSubstr("Component 'robot.nope' not found"));
}

TEST_F(SimSupervisionTest, SuspendDynamicsFreezesPhysicsButNotTime) {
  call("robot.motion", "set_speed", {1.0, 0.0});
  EXPECT_EQ(call("simulation", "suspend_dynamics").value, json("Physics is suspended"));
  double t = sim_->sim_time();
  run_for(1.0);
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(sim_->sim_time() - t, 1.0, 0.01);
  EXPECT_EQ(call("simulation", "restore_dynamics").value, json("Physics is resumed"));
  run_for(1.0);
  EXPECT_GT(pose()["x"].get<double>(), 0.5);
}

TEST_F(SimSupervisionTest, GetSceneObjectsListsBodiesWithPoses) {
  json objects = call("simulation", "get_scene_objects").value.value_or(json());
  ASSERT_TRUE(objects.contains("robot"));
  ASSERT_TRUE(objects.contains("crate1"));
  EXPECT_TRUE(objects["robot"][0].contains("robot_left_wheel"));  // children
  EXPECT_NEAR(objects["crate1"][1][0].get<double>(), 3.0, 1e-6);
  EXPECT_EQ(objects["crate1"][2].size(), 4u);
}

TEST_F(SimSupervisionTest, QuitRequestsStopAndAnswers) {
  EXPECT_FALSE(sim_->stop_requested());
  EXPECT_EQ(call("simulation", "quit").status, Status::success);
  EXPECT_TRUE(sim_->stop_requested());
}

TEST_F(SimSupervisionTest, TimeSleepCompletesAfterSimulatedTime) {
  double start = sim_->sim_time();
  RequestId id = rm_->call("time", "sleep", {0.5});
  auto o = step_until(id, 1000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_FALSE(o->value.has_value());  // bare SUCCESS, like MORSE
  EXPECT_NEAR(sim_->sim_time() - start, 0.5, 2 * sim_->timestep());
}

TEST_F(SimSupervisionTest, TwoSleepsTogetherBothSucceedEachAfterItsOwnTime) {
  double start = sim_->sim_time();
  RequestId longer = rm_->call("time", "sleep", {0.3});
  RequestId shorter = rm_->call("time", "sleep", {0.1});
  auto o = step_until(shorter, 1000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_NEAR(sim_->sim_time() - start, 0.1, 2 * sim_->timestep());
  EXPECT_FALSE(rm_->outcome(longer).has_value());
  o = step_until(longer, 1000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_NEAR(sim_->sim_time() - start, 0.3, 2 * sim_->timestep());
}

TEST_F(SimSupervisionTest, CancelOfOneSleepLeavesTheOther) {
  RequestId cancelled = rm_->call("time", "sleep", {0.2});
  RequestId kept = rm_->call("time", "sleep", {0.2});
  sim_->process_requests();
  rm_->cancel(cancelled);
  sim_->process_requests();
  auto c = rm_->outcome(cancelled);
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->status, Status::preempted);
  EXPECT_EQ(c->failure, Failure::cancelled);
  auto o = step_until(kept, 1000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
}

TEST_F(SimSupervisionTest, ASleepLeftRunningByAClientThatLeftDoesNotBlockAnother) {
  // a client asked for a long sleep and went away without cancelling it (its outcome will
  // go nowhere): another client's sleep runs beside it
  RequestId forgotten = rm_->call("time", "sleep", {1000.0});
  sim_->process_requests();
  double start = sim_->sim_time();
  RequestId id = rm_->call("time", "sleep", {0.1});
  auto o = step_until(id, 1000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_NEAR(sim_->sim_time() - start, 0.1, 2 * sim_->timestep());
  EXPECT_FALSE(rm_->outcome(forgotten).has_value());
}

TEST_F(SimSupervisionTest, ShutdownEndsEverySleepNamingIt) {
  RequestId a = rm_->call("time", "sleep", {1000.0});
  RequestId b = rm_->call("time", "sleep", {1000.0});
  sim_->process_requests();
  sim_->shutdown();
  for (RequestId id : {a, b}) {
    auto o = rm_->outcome(id);
    ASSERT_TRUE(o.has_value());
    EXPECT_EQ(o->status, Status::failed);
    EXPECT_EQ(o->failure, Failure::shutdown);
    EXPECT_EQ(o->message, "the simulation stopped before time.sleep completed");
  }
}

TEST_F(SimSupervisionTest, ListServicesSaysSleepIsConcurrentAndDetailsIsUnchanged) {
  json list = call("simulation", "list_services").value.value_or(json());
  json sleep, go;
  for (const auto& s : list) {
    if (s["component"] == "time" && s["name"] == "sleep") sleep = s;
    if (s["component"] == "robot.waypoint" && s["name"] == "goto") go = s;
  }
  EXPECT_EQ(sleep["async"], true);
  EXPECT_EQ(sleep["concurrent"], true);
  EXPECT_EQ(go["concurrent"], false);
  // pymorse reads service names only: nothing new there
  json details = call("simulation", "details").value.value_or(json());
  EXPECT_EQ(details.dump().find("concurrent"), std::string::npos);
  EXPECT_EQ(details["robots"][0]["components"]["robot.waypoint"]["services"],
            json({"goto", "setdest", "stop", "resume", "get_status", "get_properties",
                  "set_property", "get_configurations"}));
}

TEST_F(SimSupervisionTest, ResetObjectsNeverTakesTimeBack) {
  run_for(0.5);
  double before = call("time", "now").value->get<double>();
  double sim_before = sim_->sim_time();
  call("simulation", "reset_objects");
  EXPECT_GE(sim_->sim_time(), sim_before);
  EXPECT_GE(call("time", "now").value->get<double>(), before);
  run_for(0.1);
  EXPECT_NEAR(call("time", "now").value->get<double>() - before, 0.1, 0.01);
}

TEST_F(SimSupervisionTest, ASleepRunningAcrossAResetCompletesAfterItsSimulatedDuration) {
  RequestId id = rm_->call("time", "sleep", {0.5});
  sim_->process_requests();
  const std::uint64_t start = sim_->steps();
  run_for(0.2);
  call("simulation", "reset_objects");
  auto o = step_until(id, 2000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  // steps never go back: they measure the simulated time the sleep took
  EXPECT_NEAR(double(sim_->steps() - start) * sim_->timestep(), 0.5, 2 * sim_->timestep());
}

TEST_F(SimSupervisionTest, NegativeSleepFails) {
  EXPECT_EQ(call("time", "sleep", {-1.0}).status, Status::failed);
}

TEST_F(SimSupervisionTest, TimeNowFollowsSimulatedTime) {
  double t0 = call("time", "now").value->get<double>();
  run_for(1.0);
  double t1 = call("time", "now").value->get<double>();
  EXPECT_NEAR(t1 - t0, 1.0, 0.01);
  EXPECT_GT(t0, 1.6e9);  // seconds since the epoch
}

TEST_F(SimSupervisionTest, StatisticsCountSteps) {
  run_for(0.1);
  json s = call("time", "statistics").value.value_or(json());
  EXPECT_EQ(s["steps"], 50);
  EXPECT_NEAR(s["sim_time"].get<double>(), 0.1, 1e-9);
  EXPECT_EQ(s["timestep"], 0.002);
}

// ---- the mapping is a boundary (issue #17, item 6) ----

// A second transport, "partial", that serves `simulation` and `robot.pose` only, beside the
// fixture's "test" that serves everything.
class SimSupervisionBoundaryTest : public DemoSim {
 protected:
  void SetUp() override {
    DemoSim::SetUp();
    partial_ = std::make_shared<testing::RecordingManager>();
    for (const char* name : {"simulation", "robot.pose"}) {
      ComponentEntry* e = sim_->find(name);
      partial_->register_component(*e->component);
      e->interfaces.push_back("partial");
    }
    sim_->add_request_manager(partial_, "partial");
  }
  void TearDown() override {
    partial_.reset();
    DemoSim::TearDown();
  }
  Outcome call_partial(const std::string& component, const std::string& service,
                       json params = json::array()) {
    RequestId id = partial_->call(component, service, std::move(params));
    sim_->process_requests();
    auto o = partial_->outcome(id);
    EXPECT_TRUE(o.has_value()) << component << " " << service << " not answered";
    return o.value_or(Outcome::failed(Failure::internal, "no answer"));
  }

  std::shared_ptr<testing::RecordingManager> partial_;
};

TEST_F(SimSupervisionBoundaryTest, AResetOfARobotWithComponentsTheCallerDoesNotServeIsRefused) {
  // issue #35 item 10: a transport serving the robot but not its waypoint ended a goto of a
  // client of another transport, behind its back
  ComponentEntry* robot = sim_->find("robot");
  partial_->register_component(*robot->component);
  robot->interfaces.push_back("partial");
  RequestId go = rm_->call("robot.waypoint", "goto", {3.0, 0.0, 0.0});
  run_for(0.1);
  Outcome refused = call_partial("simulation", "reset", {"robot", "robot"});
  EXPECT_EQ(refused.status, Status::failed);
  EXPECT_THAT(refused.message, HasSubstr("which this transport does not serve"));
  sim_->process_requests();
  EXPECT_FALSE(rm_->outcome(go).has_value()) << "the goto was ended";
  // the transport that serves all of the robot resets it
  EXPECT_EQ(call("simulation", "reset", {"robot", "robot"}).status, Status::success);
}

TEST_F(SimSupervisionBoundaryTest,
       DeactivateRefusesAComponentTheCallerDoesNotServeAsIfItDidNotExist) {
  Outcome unserved = call_partial("simulation", "deactivate", {"robot.waypoint"});
  Outcome missing = call_partial("simulation", "deactivate", {"robot.nowhere"});
  EXPECT_EQ(unserved.status, Status::failed);
  EXPECT_EQ(unserved.message, "Component 'robot.waypoint' not found. Can't deactivate");
  EXPECT_EQ(unserved.failure, missing.failure);
  EXPECT_EQ(unserved.data, missing.data);
  EXPECT_TRUE(sim_->find("robot.waypoint")->active);
  EXPECT_EQ(call_partial("simulation", "activate", {"human"}).message,
            "Component 'human' not found. Can't activate");
  // what it serves it may still suspend, and the transport that serves the other may too
  EXPECT_EQ(call_partial("simulation", "deactivate", {"robot.pose"}).status, Status::success);
  EXPECT_FALSE(sim_->find("robot.pose")->active);
  EXPECT_EQ(call("simulation", "deactivate", {"robot.waypoint"}).status, Status::success);
  EXPECT_FALSE(sim_->find("robot.waypoint")->active);
}

TEST_F(SimSupervisionBoundaryTest, DetailsShowsOnlyWhatTheCallerServes) {
  json d = call_partial("simulation", "details").value.value_or(json());
  ASSERT_EQ(d["robots"].size(), 1u);  // not the human
  json robot = d["robots"][0];
  EXPECT_EQ(robot["name"], "robot");  // it holds robot.pose
  EXPECT_EQ(robot["components"].size(), 1u);
  EXPECT_EQ(robot["components"]["robot.pose"]["services"],
            json({"get_local_data", "get_properties", "set_property", "get_configurations"}));
  EXPECT_EQ(robot["components"]["robot.pose"]["service_interfaces"], json({"test", "partial"}));
  // the transport that serves everything still sees everything
  json all = call("simulation", "details").value.value_or(json());
  EXPECT_EQ(all["robots"].size(), 2u);
  EXPECT_EQ(all["robots"][0]["components"].size(), 4u);
}

TEST_F(SimSupervisionBoundaryTest, ListRobotsAndListServicesShowOnlyWhatTheCallerServes) {
  EXPECT_EQ(call_partial("simulation", "list_robots").value, json({"robot"}));
  json list = call_partial("simulation", "list_services").value.value_or(json());
  std::set<std::string> components;
  for (const auto& s : list) components.insert(s["component"].get<std::string>());
  EXPECT_EQ(components, (std::set<std::string>{"robot.pose", "simulation"}));
  EXPECT_EQ(call("simulation", "list_robots").value, json({"robot", "human"}));
}

TEST_F(SimSupervisionBoundaryTest, GetSceneObjectsIsTheWholeSceneForEveryCaller) {
  // bodies, not components: the world every client sees
  EXPECT_EQ(call_partial("simulation", "get_scene_objects").value,
            call("simulation", "get_scene_objects").value);
}

TEST_F(SimSupervisionBoundaryTest, CalledDirectlyTheServicesSeeEverything) {
  // the host (no request running) is not bounded by any transport
  auto* supervision = static_cast<SupervisionServices*>(sim_->find("simulation")->component.get());
  EXPECT_EQ(supervision->list_robots(), (std::vector<std::string>{"robot", "human"}));
  supervision->deactivate("human");
  EXPECT_FALSE(sim_->find("human")->active);
}

// ---- the transports' allow and deny lists (issue #17, access control) ----

// "partial" may call the `simulation` services but quit, and nothing of robot.pose.
class SimSupervisionAccessTest : public SimSupervisionBoundaryTest {
 protected:
  void SetUp() override {
    SimSupervisionBoundaryTest::SetUp();
    partial_->set_access(ServiceAccess({{"simulation.*"}}, {"simulation.quit"}));
  }
};

// "component.service" -> the transports list_services gives it.
std::map<std::string, json> by_name(const json& list) {
  std::map<std::string, json> out;
  for (const auto& s : list)
    out[s["component"].get<std::string>() + "." + s["name"].get<std::string>()] = s["transports"];
  return out;
}

TEST_F(SimSupervisionAccessTest, ListServicesShowsOnlyWhatTheCallersListsLetItCall) {
  auto partial = by_name(call_partial("simulation", "list_services").value.value_or(json()));
  EXPECT_FALSE(partial.count("simulation.quit"));
  EXPECT_FALSE(partial.count("robot.pose.get_local_data"));
  ASSERT_TRUE(partial.count("simulation.details"));
  EXPECT_EQ(partial["simulation.details"], json({"test", "partial"}));
  // the transport without lists sees them all, each with the transports that let it through
  auto all = by_name(call("simulation", "list_services").value.value_or(json()));
  EXPECT_EQ(all["simulation.quit"], json({"test"}));
  EXPECT_EQ(all["robot.pose.get_local_data"], json({"test"}));
  EXPECT_EQ(all["simulation.details"], json({"test", "partial"}));
  // partial: the simulation services but quit, nothing else
  std::size_t simulation_services = 0;
  for (const auto& [name, transports] : all)
    simulation_services += name.rfind("simulation.", 0) == 0;
  EXPECT_EQ(partial.size(), simulation_services - 1);
}

TEST_F(SimSupervisionAccessTest, DetailsListsAServedComponentWithoutTheServicesItMayNotCall) {
  json d = call_partial("simulation", "details").value.value_or(json());
  ASSERT_EQ(d["robots"].size(), 1u);
  // robot.pose is served (the mapping) but none of its services is callable
  ASSERT_TRUE(d["robots"][0]["components"].contains("robot.pose")) << d;
  EXPECT_FALSE(d["robots"][0]["components"]["robot.pose"].contains("services")) << d;
  EXPECT_FALSE(d["robots"][0]["components"]["robot.pose"].contains("service_interfaces")) << d;
  json all = call("simulation", "details").value.value_or(json());
  EXPECT_EQ(all["robots"][0]["components"]["robot.pose"]["services"],
            json({"get_local_data", "get_properties", "set_property", "get_configurations"}));
}

TEST_F(SimSupervisionAccessTest, ADeniedSupervisionServiceDoesNotRun) {
  EXPECT_EQ(call_partial("simulation", "quit").failure, Failure::unknown_service);
  EXPECT_FALSE(sim_->stop_requested());
  EXPECT_EQ(call_partial("simulation", "list_robots").value, json({"robot"}));
}

}  // namespace
}  // namespace simgate::sim
