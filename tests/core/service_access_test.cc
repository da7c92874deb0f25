// ServiceAccess (core/src/service_access.cc): a transport's allow and deny lists of service
// patterns, '*' matching any characters; and how a RequestManager applies them
// (RequestManager::set_access): a denied service is refused as an unknown one before it
// runs and is missing from everything the manager describes (issue #17, access control).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "simgate/core/call_context.h"
#include "simgate/core/service_access.h"
#include "test_manager.h"

namespace simgate {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing::TestManager;

bool matches(const char* pattern, const char* component, const char* service) {
  return ServiceAccess::matches(pattern, component, service);
}

TEST(ServiceAccessTest, APatternMatchesTheQualifiedNameWithStarsAcrossDots) {
  EXPECT_TRUE(matches("simulation.quit", "simulation", "quit"));
  EXPECT_FALSE(matches("simulation.quit", "simulation", "quit2"));
  EXPECT_FALSE(matches("simulation.quit", "simulation2", "quit"));
  EXPECT_TRUE(matches("simulation.*", "simulation", "reset_objects"));
  EXPECT_FALSE(matches("simulation.*", "time", "now"));
  EXPECT_TRUE(matches("*.quit", "simulation", "quit"));
  EXPECT_TRUE(matches("*.quit", "robot.arm", "quit"));
  EXPECT_FALSE(matches("*.quit", "simulation", "quitter"));
  // a robot's pattern covers its components' services; not another robot's
  EXPECT_TRUE(matches("robot.*", "robot", "stop"));
  EXPECT_TRUE(matches("robot.*", "robot.motion", "set_speed"));
  EXPECT_FALSE(matches("robot.*", "robot2.motion", "set_speed"));
  EXPECT_TRUE(matches("robot*", "robot2.motion", "set_speed"));
  EXPECT_TRUE(matches("robot.motion.set_speed", "robot.motion", "set_speed"));
  EXPECT_TRUE(matches("*.motion.set_*", "robot.motion", "set_speed"));
  EXPECT_TRUE(matches("*", "anything", "at_all"));
  EXPECT_TRUE(matches("**.*", "a", "b"));
  // "robot.motion" names the service `motion` of `robot`, not the component
  EXPECT_FALSE(matches("robot.motion", "robot.motion", "set_speed"));
  EXPECT_TRUE(matches("robot.motion", "robot", "motion"));
}

TEST(ServiceAccessTest, MatchingALongNameAgainstManyStarsStaysLinearEnough) {
  // the backtracking match never recurses: a pathological pattern on a long name is quick
  std::string name(10000, 'a');
  EXPECT_FALSE(ServiceAccess::matches("*a*a*a*a*a*a*a*a*b", name, "a"));
  EXPECT_TRUE(ServiceAccess::matches("*a*a*a*a*a*a*a*a*.a", name, "a"));
}

TEST(ServiceAccessTest, MalformedPatternsAreRefusedWithTheReason) {
  EXPECT_EQ(ServiceAccess::pattern_error("simulation.quit"), "");
  EXPECT_EQ(ServiceAccess::pattern_error("*"), "");
  EXPECT_EQ(ServiceAccess::pattern_error("robot-1.*"), "");
  EXPECT_EQ(ServiceAccess::pattern_error(""), "is empty");
  EXPECT_THAT(
      ServiceAccess::pattern_error("simulation"),
      HasSubstr(
          "has no '.' between a component and a service (\"simulation.*\": every service of a "
          "component 'simulation'; \"*.simulation\": a service 'simulation' of any component)"));
  EXPECT_THAT(ServiceAccess::pattern_error("simulation.qu?t"),
              HasSubstr("has a character other than"));
  EXPECT_THAT(ServiceAccess::pattern_error("robot.[a-z]*"),
              HasSubstr("has a character other than"));
  EXPECT_THAT(ServiceAccess::pattern_error("simulation. quit"),
              HasSubstr("has a character other than"));
  EXPECT_EQ(ServiceAccess::pattern_error(".quit"), "has an empty name between dots");
  EXPECT_EQ(ServiceAccess::pattern_error("simulation."), "has an empty name between dots");
  EXPECT_EQ(ServiceAccess::pattern_error("robot..quit"), "has an empty name between dots");
  try {
    ServiceAccess({{"robot.*"}}, {"simulation.quit", "quit"});
    FAIL() << "a malformed deny pattern was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("deny pattern 'quit' has no '.'"));
  }
}

TEST(ServiceAccessTest, ByDefaultEverythingIsAllowed) {
  ServiceAccess access;
  EXPECT_TRUE(access.allows_everything());
  EXPECT_TRUE(access.allows("simulation", "quit"));
  EXPECT_EQ(access.describe(), "");
}

TEST(ServiceAccessTest, WithAnAllowListOnlyWhatMatchesItIsAllowed) {
  ServiceAccess access({{"robot.*", "time.now"}}, {});
  EXPECT_FALSE(access.allows_everything());
  EXPECT_TRUE(access.allows("robot.motion", "set_speed"));
  EXPECT_TRUE(access.allows("time", "now"));
  EXPECT_FALSE(access.allows("time", "sleep"));
  EXPECT_FALSE(access.allows("simulation", "details"));
  // an empty allow list allows nothing
  EXPECT_FALSE(ServiceAccess(std::vector<std::string>{}, {}).allows("robot", "stop"));
}

TEST(ServiceAccessTest, DenyWinsOverAllow) {
  ServiceAccess access({{"simulation.*"}}, {"simulation.quit", "*.reset_objects"});
  EXPECT_TRUE(access.allows("simulation", "details"));
  EXPECT_FALSE(access.allows("simulation", "quit"));
  EXPECT_FALSE(access.allows("simulation", "reset_objects"));
  ServiceAccess deny_only(std::nullopt, {"simulation.quit"});
  EXPECT_TRUE(deny_only.allows("robot.motion", "set_speed"));
  EXPECT_FALSE(deny_only.allows("simulation", "quit"));
  EXPECT_EQ(access.describe(), "allow simulation.*; deny simulation.quit, *.reset_objects");
  EXPECT_EQ(deny_only.describe(), "deny simulation.quit");
  EXPECT_EQ(ServiceAccess(std::vector<std::string>{}, {}).describe(), "allow nothing");
}

// ---- the manager applies them ----

class RequestManagerAccessTest : public ::testing::Test {
 protected:
  void SetUp() override {
    rm.register_service("simulation", [this] { ++quits; }, "quit");
    rm.register_service("simulation", [] { return 1; }, "details");
    rm.register_service("robot.pose", [] { return 2; }, "get_local_data");
    rm.register_service("robot.teleport", [this] { ++teleports; }, "translate");
  }
  TestManager rm;
  int quits = 0;      // simulation quit ran
  int teleports = 0;  // robot.teleport translate ran
};

// `o`'s message and data with `name` replaced by NAME (to compare two refusals)
std::string hidden(const Outcome& o, const std::string& name) {
  std::string text = o.message + " " + o.data.dump();
  for (auto at = text.find(name); at != std::string::npos; at = text.find(name, at + 4))
    text.replace(at, name.size(), "NAME");
  return text;
}

TEST_F(RequestManagerAccessTest, ADeniedServiceIsRefusedAsAnUnknownOneAndDoesNotRun) {
  rm.set_access(ServiceAccess(std::nullopt, {"simulation.quit"}));
  auto denied = rm.run("simulation", "quit");
  auto missing = rm.run("simulation", "quiz");
  ASSERT_TRUE(denied && missing);
  EXPECT_EQ(quits, 0);
  EXPECT_EQ(denied->status, Status::failed);
  EXPECT_EQ(denied->failure, Failure::unknown_service);
  EXPECT_EQ(denied->message,
            "The request quit has not been registered in Test service manager: component "
            "'simulation' has no service 'quit' (services: details)");
  // word for word what a service that does not exist gets: the lists do not show through
  EXPECT_EQ(hidden(*denied, "quit"), hidden(*missing, "quiz"));
  EXPECT_EQ(denied->failure, missing->failure);
  EXPECT_EQ(rm.run("simulation", "details")->value, json(1));
}

TEST_F(RequestManagerAccessTest, AnAllowListLetsOnlyItsServicesRun) {
  rm.set_access(ServiceAccess({{"robot.*"}}, {"robot.teleport.*"}));
  EXPECT_EQ(rm.run("robot.pose", "get_local_data")->value, json(2));
  EXPECT_EQ(rm.run("robot.teleport", "translate")->failure, Failure::unknown_service);
  EXPECT_EQ(rm.run("simulation", "details")->failure, Failure::unknown_service);
  EXPECT_EQ(teleports, 0);
  // a component all of whose services are denied is still served (the mapping's part): it
  // is known, with no service to call
  EXPECT_TRUE(rm.serves_component("robot.teleport"));
  EXPECT_THAT(rm.run("robot.teleport", "translate")->message,
              HasSubstr("component 'robot.teleport' has no service 'translate'"));
}

TEST_F(RequestManagerAccessTest, DescriptorsAndServicesListOnlyCallableServices) {
  rm.set_access(
      ServiceAccess({{"robot.*", "simulation.*"}}, {"simulation.quit", "robot.teleport.*"}));
  std::vector<std::string> names;
  for (const auto& d : rm.descriptors()) names.push_back(d.qualified_name());
  EXPECT_EQ(names, std::vector<std::string>({"robot.pose.get_local_data", "simulation.details"}));
  EXPECT_EQ(rm.services(), (std::map<std::string, std::vector<std::string>>{
                               {"robot.pose", {"get_local_data"}}, {"simulation", {"details"}}}));
  EXPECT_TRUE(rm.may_call("simulation", "details"));
  EXPECT_FALSE(rm.may_call("simulation", "quit"));
  EXPECT_FALSE(rm.may_call("robot.teleport", "translate"));
  EXPECT_FALSE(rm.may_call("simulation", "nothing"));  // allowed, but not registered
  EXPECT_EQ(rm.components(),
            std::vector<std::string>({"robot.pose", "robot.teleport", "simulation"}));
}

TEST_F(RequestManagerAccessTest, RefusalsNeitherListNorSuggestADeniedService) {
  rm.set_access(ServiceAccess(std::nullopt, {"robot.pose.*", "simulation.quit"}));
  // `robot get_local_data` would suggest robot.pose; `simulation quiet` would suggest quit
  EXPECT_THAT(rm.run("robot", "get_local_data")->message, Not(HasSubstr("robot.pose")));
  EXPECT_THAT(rm.run("simulation", "quiet")->message, Not(HasSubstr("quit")));
  EXPECT_THAT(rm.run("robot.pose", "get_local_data")->message, Not(HasSubstr("services:")));
}

TEST_F(RequestManagerAccessTest, NewListsApplyToTheNextCallEvenOfAServiceJustCalled) {
  // a pipelining client's repeated call is answered from the previous lookup: new lists must
  // not let it through
  EXPECT_EQ(rm.run("robot.pose", "get_local_data")->value, json(2));
  rm.set_access(ServiceAccess(std::nullopt, {"robot.pose.get_local_data"}));
  EXPECT_EQ(rm.run("robot.pose", "get_local_data")->failure, Failure::unknown_service);
  rm.set_access(ServiceAccess());
  EXPECT_EQ(rm.run("robot.pose", "get_local_data")->value, json(2));
}

TEST_F(RequestManagerAccessTest, ServicesRegisteredAfterTheListsAreFilteredToo) {
  rm.set_access(ServiceAccess(std::nullopt, {"*.quit"}));
  rm.register_service("human", [] {}, "quit");
  EXPECT_EQ(rm.run("human", "quit")->failure, Failure::unknown_service);
  EXPECT_FALSE(rm.may_call("human", "quit"));
  EXPECT_TRUE(rm.serves_component("human"));
}

TEST_F(RequestManagerAccessTest, ARunningServiceSeesItsCallersLists) {
  // what simulation list_services and details use to show only what the caller may call
  bool saw_quit = true, saw_details = false;
  rm.register_service(
      "simulation",
      [&] {
        saw_quit = caller_may_call("simulation", "quit");
        saw_details = caller_may_call("simulation", "details");
      },
      "look");
  rm.set_access(ServiceAccess(std::nullopt, {"simulation.quit"}));
  rm.run("simulation", "look");
  EXPECT_FALSE(saw_quit);
  EXPECT_TRUE(saw_details);
  EXPECT_TRUE(caller_may_call("simulation", "quit"));  // the host, outside any request
}

// ---- consoles: process-wide services (issue #35, item 5)

TEST(ServiceAccessTest, OnlyAConsoleAllowsProcessWideServices) {
  ServiceDescriptor terminate;  // members set one by one: a designated list leaves some out
  terminate.component = "simulation";
  terminate.name = "terminate";
  terminate.process_wide = true;
  ServiceDescriptor details;
  details.component = "simulation";
  details.name = "details";
  EXPECT_TRUE(ServiceAccess().allows(terminate));  // the default (a host, tests) is a console
  const ServiceAccess no_console(std::nullopt, {}, /*console=*/false);
  EXPECT_FALSE(no_console.allows(terminate));
  EXPECT_TRUE(no_console.refuses_as_no_console(terminate));
  EXPECT_TRUE(no_console.allows(details));
  EXPECT_FALSE(no_console.allows_everything());
  EXPECT_EQ(no_console.describe(), "no process-wide services");
  // a console's lists still apply, and a denied service is not refused "as no console"
  const ServiceAccess console(std::nullopt, {"simulation.terminate"}, /*console=*/true);
  EXPECT_FALSE(console.allows(terminate));
  EXPECT_FALSE(console.refuses_as_no_console(terminate));
  const ServiceAccess denied(std::nullopt, {"simulation.terminate"}, /*console=*/false);
  EXPECT_FALSE(denied.refuses_as_no_console(terminate));
}

TEST_F(RequestManagerAccessTest, ATransportThatIsNoConsoleRefusesProcessWideServicesSayingWhy) {
  int terminations = 0;
  rm.register_service("simulation", [&] { ++terminations; }, "terminate").process_wide();
  rm.set_access(ServiceAccess(std::nullopt, {}, /*console=*/false));
  auto refused = rm.run("simulation", "terminate");
  ASSERT_TRUE(refused);
  EXPECT_EQ(terminations, 0);
  EXPECT_EQ(refused->status, Status::failed);
  EXPECT_EQ(refused->failure, Failure::unknown_service);
  EXPECT_THAT(refused->message,
              HasSubstr("simulation.terminate acts on the whole process, and this transport is "
                        "not a console"));
  EXPECT_FALSE(rm.may_call("simulation", "terminate"));
  for (const auto& d : rm.descriptors()) EXPECT_NE(d.qualified_name(), "simulation.terminate");
  // nor is it listed or suggested in another refusal
  EXPECT_THAT(rm.run("simulation", "terminat")->message, Not(HasSubstr("terminate")));
  EXPECT_EQ(rm.run("simulation", "quit")->status, Status::success);  // not process-wide here
  // a console runs it
  rm.set_access(ServiceAccess(std::nullopt, {}, /*console=*/true));
  EXPECT_EQ(rm.run("simulation", "terminate")->status, Status::success);
  EXPECT_EQ(terminations, 1);
}

TEST(ServiceDescriptorTest, AProcessWideServiceSaysSoInItsDescription) {
  ServiceDescriptor d;
  d.component = "simulation";
  d.name = "terminate";
  EXPECT_FALSE(d.to_json().contains("process_wide"));
  d.process_wide = true;
  EXPECT_EQ(d.to_json()["process_wide"], true);
}

}  // namespace
}  // namespace simgate
