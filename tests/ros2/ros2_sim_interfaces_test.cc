// The ros2 transport's services in simgate's terms (protocols/ros2/ros2_sim_interfaces.h):
// simulation_interfaces' states, scopes, features and results; rmw_cyclonedds' service topics
// and ids; the entity filter; the request header in the generated types (ros2_srvs.idl).
#include <gtest/gtest.h>

#include <cstddef>
#include <set>
#include <stdexcept>

#include "ros2_sim_interfaces.h"
#include "ros2_srvs.h"

namespace simgate::ros2 {
namespace {

TEST(Ros2SimInterfacesTest, RunStatesAreSimulationStates) {
  EXPECT_EQ(sim_state_of("playing"), SimState::playing);
  EXPECT_EQ(sim_state_of("paused"), SimState::paused);
  EXPECT_EQ(sim_state_of("stepping"), SimState::paused);  // paused, taking a client's steps
  EXPECT_EQ(sim_state_of("quitting"), SimState::quitting);
  EXPECT_FALSE(sim_state_of("stopped"));
  EXPECT_FALSE(sim_state_of(""));
}

TEST(Ros2SimInterfacesTest, ResetScopesAreSimgatesOrSayWhyNot) {
  std::string why;
  EXPECT_EQ(reset_scope_of(0, why), "all");  // SCOPE_DEFAULT
  EXPECT_EQ(reset_scope_of(k_scope_time | k_scope_state, why), "all");
  EXPECT_EQ(reset_scope_of(k_scope_state, why), "state");
  EXPECT_TRUE(why.empty());
  EXPECT_FALSE(reset_scope_of(k_scope_spawned, why));
  EXPECT_NE(why.find("SCOPE_SPAWNED"), std::string::npos) << why;
  why.clear();
  EXPECT_FALSE(reset_scope_of(255, why));  // SCOPE_ALL includes SCOPE_SPAWNED
  EXPECT_NE(why.find("SCOPE_SPAWNED"), std::string::npos) << why;
  why.clear();
  EXPECT_FALSE(reset_scope_of(k_scope_time, why));
  EXPECT_NE(why.find("SCOPE_TIME"), std::string::npos) << why;
}

TEST(Ros2SimInterfacesTest, FeaturesNeedEveryServiceTheirRosServicesCall) {
  const auto all = offered_features([](const std::string&) { return true; });
  EXPECT_EQ(all, (std::vector<std::uint16_t>{0, 1, 5, 9, 10, 11, 12, 20, 21, 22, 24, 25, 26, 31, 32,
                                             33}));
  EXPECT_TRUE(offered_features([](const std::string&) { return false; }).empty());
  // play denied: SIMULATION_STATE_SETTING goes, pausing (26) stays
  const auto no_play = offered_features([](const std::string& s) { return s != "play"; });
  const std::set<std::uint16_t> features(no_play.begin(), no_play.end());
  EXPECT_FALSE(features.count(25));
  EXPECT_TRUE(features.count(26));
  // spawning asks which names are taken first
  const auto no_list = offered_features([](const std::string& s) { return s != "list_entities"; });
  EXPECT_FALSE(std::set<std::uint16_t>(no_list.begin(), no_list.end()).count(0));
}

TEST(Ros2SimInterfacesTest, OutcomesBecomeTheStandardsResults) {
  EXPECT_TRUE(result_of(Outcome::success(json(1))).is_ok());
  const ServiceResult unknown =
      result_of(Outcome::failed(Failure::unknown_service, "no service 'step' here"));
  EXPECT_EQ(unknown.code, static_cast<std::uint8_t>(ResultCode::feature_unsupported));
  EXPECT_EQ(unknown.message, "no service 'step' here");
  const Outcome missing = Outcome::failed(Failure::bad_arguments, "Object 'x' does not appear",
                                          json{{"parameter", "name"}});
  EXPECT_EQ(result_of(missing, "name").code, static_cast<std::uint8_t>(ResultCode::not_found));
  // the same refusal for another parameter is no "not found"
  EXPECT_EQ(result_of(missing, "object_name").code,
            static_cast<std::uint8_t>(ResultCode::operation_failed));
  const Outcome playing =
      Outcome::failed(Failure::service_error, "pause it first", json{{"state", "playing"}});
  EXPECT_EQ(result_of(playing).code, static_cast<std::uint8_t>(ResultCode::incorrect_state));
  EXPECT_EQ(result_of(Outcome::failed(Failure::timeout, "too late")).code,
            static_cast<std::uint8_t>(ResultCode::operation_failed));
  Outcome preempted;
  preempted.status = Status::preempted;
  preempted.failure = Failure::preempted;
  preempted.message = "a reset preempted it";
  EXPECT_EQ(result_of(preempted).code, static_cast<std::uint8_t>(ResultCode::operation_failed));
  EXPECT_EQ(result_of(preempted).message, "a reset preempted it");
}

TEST(Ros2SimInterfacesTest, ServiceTopicsAreRmwCycloneddsNames) {
  EXPECT_EQ(service_request_topic("/step_simulation"), "rq/step_simulationRequest");
  EXPECT_EQ(service_reply_topic("/step_simulation"), "rr/step_simulationReply");
  EXPECT_EQ(service_request_topic("/sim/simgate/call"), "rq/sim/simgate/callRequest");
}

TEST(Ros2SimInterfacesTest, ServiceIdsAreWrittenAsRmwCycloneddsWritesThem) {
  // the participant's GUID prefix, then the counter big endian; the first byte as two hex
  // digits, every other one without leading zeros after a '.'
  std::array<std::uint8_t, 16> guid{0x01, 0x0f, 0xa0, 0x00, 0x10, 0x20,
                                    0x30, 0x40, 0x50, 0x60, 0x70, 0x80};
  EXPECT_EQ(service_user_data(guid, 0x0102),
            "serviceid=01.f.a0.0.10.20.30.40.50.60.70.80.0.0.1.2;");
  guid[0] = 0x0a;
  EXPECT_EQ(service_user_data(guid, 1).substr(0, 13), "serviceid=0a.");
}

TEST(Ros2SimInterfacesTest, UserDataValuesAreFoundByKey) {
  EXPECT_EQ(user_data_value("clientid=01.2.3;typehash=RIHS01_ab;", "clientid"), "01.2.3");
  EXPECT_EQ(user_data_value("enclave=/;clientid=x;", "clientid"), "x");
  EXPECT_EQ(user_data_value("clientid=x", "clientid"), "x");  // no trailing ';'
  EXPECT_FALSE(user_data_value("serviceid=x;", "clientid"));
  EXPECT_FALSE(user_data_value("", "clientid"));
  EXPECT_FALSE(user_data_value("myclientid=x;", "clientid"));
}

TEST(Ros2SimInterfacesTest, EntityFiltersArePosixExtendedRegularExpressions) {
  EXPECT_TRUE(EntityFilter("").matches("anything"));
  const EntityFilter robot("^robot($|_)");
  EXPECT_TRUE(robot.matches("robot"));
  EXPECT_TRUE(robot.matches("robot_left_wheel"));
  EXPECT_FALSE(robot.matches("robotic"));
  EXPECT_FALSE(robot.matches("the_robot"));
  EXPECT_TRUE(EntityFilter("crate[0-9]+").matches("crate12"));  // ERE: + without '\'
  EXPECT_TRUE(EntityFilter("a|b").matches("b"));
  EXPECT_THROW(EntityFilter("(robot"), std::invalid_argument);
  try {
    EntityFilter bad("[z-a]");
    FAIL() << "a bad range was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("[z-a]"), std::string::npos) << e.what();
  }
  // a pattern that backtracks exponentially elsewhere stays quick
  EXPECT_FALSE(EntityFilter("(a*)*b").matches(std::string(40, 'a')));
}

TEST(Ros2SimInterfacesTest, EntityStatesAreReadBack) {
  EntityMotion motion;
  const json state{{"pose", pose_json({1, 2, 3}, {0, 0, 0.6, 0.8})},
                   {"twist", twist_json({0.1, 0, 0}, {0, 0, 0.5})}};
  ASSERT_TRUE(entity_motion(state, motion));
  EXPECT_EQ(motion.position, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(motion.orientation, (std::array<double, 4>{0, 0, 0.6, 0.8}));
  EXPECT_EQ(motion.angular[2], 0.5);
  EXPECT_FALSE(entity_motion(json{{"pose", state["pose"]}}, motion));
  EXPECT_FALSE(entity_motion(json::array(), motion));
  json short_position = state;
  short_position["pose"]["position"] = {1, 2};
  EXPECT_FALSE(entity_motion(short_position, motion));
}

TEST(Ros2SimInterfacesTest, EveryRequestAndReplyBeginsWithRmwCycloneddsHeader) {
  // the client's id then the sequence number, 16 bytes, before the message's fields
#define SIMGATE_EXPECT_HEADER(T)                     \
  EXPECT_EQ(offsetof(T, rmw_client_guid), 0u) << #T; \
  EXPECT_EQ(offsetof(T, rmw_sequence), 8u) << #T
  SIMGATE_EXPECT_HEADER(simulation_interfaces_srv_dds__GetSimulatorFeatures_Request_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_srv_dds__GetSimulatorFeatures_Response_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_srv_dds__StepSimulation_Request_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_srv_dds__StepSimulation_Response_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_srv_dds__SpawnEntity_Request_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_srv_dds__GetEntitiesStates_Response_);
  SIMGATE_EXPECT_HEADER(simgate_interfaces_srv_dds__Call_Request_);
  SIMGATE_EXPECT_HEADER(simgate_interfaces_srv_dds__Call_Response_);
#undef SIMGATE_EXPECT_HEADER
  EXPECT_STREQ(simulation_interfaces_srv_dds__StepSimulation_Request__desc.m_typename,
               "simulation_interfaces::srv::dds_::StepSimulation_Request_");
}

}  // namespace
}  // namespace simgate::ros2
