// list_simgates(): the simgates of a domain, told apart by the partition of their catalog
// writers (docs/transports/dds.md, "Catalog"; docs/worlds.md, "Across hosts"). Two DDS
// transports in two partitions of one process play two hosts, on loopback.
#include <set>
#include <string>
#include <vector>

#include "dds_transport_fixture.h"

namespace simgate::dds::test {
namespace {

using client::DdsSimgate;
using client::is_partition_pattern;
using client::list_simgates;

DdsClientOptions options_for(const std::string& partition) {
  return DdsClientOptions::from_json(client_options(partition));
}

std::set<std::string> names(const json& services) {
  std::set<std::string> out;
  for (const json& s : services)
    out.insert(s.at("component").get<std::string>() + "." + s.at("name").get<std::string>());
  return out;
}

const std::set<std::string> k_services = {"calc.add",    "calc.echo",  "calc.fail", "calc.count",
                                          "calc.whoami", "robot.goto", "arm.grasp", "tool.use"};

TEST_F(DdsTransportTest, ListSimgatesTellsTheSimgatesOfAPatternApartByPartition) {
  // both serve the same components: the catalog's key is the component, so a reader of both
  // receives each instance from two writers
  auto a = make_server(test_partition("hostA"), "a");
  auto b = make_server(test_partition("hostB"), "b");
  auto b1 = b->attach_world(1);  // host B's world 1, under a lock of its own
  b1->set_gate(std::make_shared<SimulationGate>());
  b1->register_service("calc", [](double x, double y) { return x * y; }, "mul", {"x", "y"});
  SimThread sim_a(a);
  SimThread sim_b(b);
  SimThread sim_b1(b1);

  const std::vector<DdsSimgate> simgates =
      list_simgates(options_for(test_partition("host*")), 10s, 200ms);
  ASSERT_EQ(simgates.size(), 2u);
  EXPECT_EQ(simgates[0].partition, test_partition("hostA"));
  EXPECT_EQ(simgates[1].partition, test_partition("hostB"));
  EXPECT_EQ(simgates[0].server.size(), 32u);
  EXPECT_NE(simgates[0].server, simgates[1].server);
  EXPECT_TRUE(simgates[0].whole && simgates[1].whole);
  EXPECT_EQ(simgates[0].worlds, (std::vector<std::string>{"w0"}));
  EXPECT_EQ(simgates[1].worlds, (std::vector<std::string>{"w0", "w1"}));
  EXPECT_EQ(names(simgates[0].services), k_services);
  std::set<std::string> with_world = k_services;
  with_world.insert("w1/calc.mul");
  EXPECT_EQ(names(simgates[1].services), with_world);
  const json data = simgates[1].to_json();
  EXPECT_EQ(data["partition"], test_partition("hostB"));
  EXPECT_EQ(data["worlds"], json({"w0", "w1"}));
  EXPECT_FALSE(data.contains("whole"));

  // a partition named in full lists that simgate alone; a client there lists and calls it
  const auto one = list_simgates(options_for(test_partition("hostB")), 10s, 0ms);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].server, simgates[1].server);
  auto client_a = make_client(test_partition("hostA"));
  EXPECT_EQ(names(client_a->list_services(10s)), k_services);
  EXPECT_EQ(client_a->call("calc", "whoami", nullptr, 10s).value, json("a"));
  auto client_b = make_client(test_partition("hostB"));
  EXPECT_EQ(client_b->call("w1/calc", "mul", {3, 4}, 10s).value, json(12.0));
}

TEST_F(DdsTransportTest, ListSimgatesSeesACatalogChangeOfOneSimgateOnly) {
  auto a = make_server(test_partition("hostA"));
  auto b = make_server(test_partition("hostB"));
  SimThread sim_a(a);
  SimThread sim_b(b);
  ASSERT_EQ(list_simgates(options_for(test_partition("host?")), 10s, 200ms).size(), 2u);
  {
    std::lock_guard lock(*a->gate());  // as the simulation removes a component
    ASSERT_TRUE(a->unregister_component("robot", "deleted"));
  }
  // the catalog changes on the DDS thread: look until it has (bounded)
  std::vector<DdsSimgate> simgates;
  std::set<std::string> without_robot = k_services;
  without_robot.erase("robot.goto");
  ASSERT_TRUE(eventually([&] {
    simgates = list_simgates(options_for(test_partition("host?")), 10s, 0ms);
    return simgates.size() == 2 && names(simgates[0].services) == without_robot;
  }));
  EXPECT_EQ(names(simgates[1].services), k_services);  // host B's "robot" is still there
}

// Against the convention (`simgate list` notes it): both are listed, apart by server.
TEST_F(DdsTransportTest, ListSimgatesListsTwoSimgatesOfOnePartitionBoth) {
  auto first = make_server(test_partition("host"), "first");
  auto second = make_server(test_partition("host"), "second");
  SimThread sim_first(first);
  SimThread sim_second(second);
  const auto simgates = list_simgates(options_for(test_partition("h*")), 10s, 200ms);
  ASSERT_EQ(simgates.size(), 2u);
  EXPECT_EQ(simgates[0].partition, test_partition("host"));
  EXPECT_EQ(simgates[1].partition, test_partition("host"));
  EXPECT_NE(simgates[0].server, simgates[1].server);
  EXPECT_EQ(names(simgates[0].services), k_services);
  EXPECT_EQ(names(simgates[1].services), k_services);
}

TEST_F(DdsTransportTest, ListSimgatesMatchingNothingNamesTheDomainThePatternAndTheWait) {
  try {
    list_simgates(options_for(test_partition("nohost*")), 300ms);
    FAIL() << "list_simgates found a simgate";
  } catch (const ClientError& e) {
    const std::string what = e.what();
    EXPECT_NE(
        what.find("no simgate in domain " + std::to_string(test_domain()) +
                  " whose partition matches '" + test_partition("nohost*") + "' within 300 ms"),
        std::string::npos)
        << what;
    EXPECT_NE(what.find("network settings"), std::string::npos) << what;
  }
}

TEST_F(DdsTransportTest, AClientRefusesAPartitionPattern) {
  EXPECT_TRUE(is_partition_pattern("*"));
  EXPECT_TRUE(is_partition_pattern("host?"));
  EXPECT_FALSE(is_partition_pattern("hostA"));
  try {
    DdsClient client(options_for("host*"));
    FAIL() << "a client in partition 'host*' was made";
  } catch (const ClientError& e) {
    EXPECT_NE(std::string(e.what()).find("partition 'host*' is a pattern"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace simgate::dds::test
