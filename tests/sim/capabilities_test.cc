// SimCapabilities: `simulation get_capabilities` lists a feature exactly when the services
// providing it are registered on `simulation`.
#include <set>
#include <string>

#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using testing::DemoSim;

class SimCapabilitiesTest : public DemoSim {
 protected:
  std::set<std::string> simulation_services() {
    std::set<std::string> names;
    for (const auto& s : sim_->find("simulation")->component->services())
      names.insert(s->descriptor().name);
    return names;
  }
};

TEST_F(SimCapabilitiesTest,
       EveryListedFeatureHasItsServicesAndEveryFeatureWhoseServicesExistIsListed) {
  json caps = *call("simulation", "get_capabilities").value;
  ASSERT_TRUE(caps["features"].is_array());
  const std::set<std::string> offered = simulation_services();
  std::set<int> ids;
  for (const json& f : caps["features"]) {
    ids.insert(f["id"].get<int>());
    ASSERT_FALSE(f["services"].empty()) << f.dump();
    for (const json& s : f["services"])
      EXPECT_TRUE(offered.count(s.get<std::string>())) << f.dump();
  }
  // the stepping, state and spawning features, by their services
  EXPECT_EQ(ids.count(31) == 1, offered.count("step") == 1);
  EXPECT_EQ(ids.count(26) == 1, offered.count("pause") == 1);
  EXPECT_EQ(ids.count(10) == 1, offered.count("get_entity_state") == 1);
  EXPECT_EQ(ids.count(0) == 1, offered.count("spawn_entity") == 1);
  EXPECT_EQ(caps["spawn_formats"],
            offered.count("spawn_entity") ? json({"mjcf", "urdf"}) : json::array());
}

TEST_F(SimCapabilitiesTest, TheWorldControlGroupsOfferEveryFeatureSimgateHas) {
  json caps = *call("simulation", "get_capabilities").value;
  std::set<int> ids;
  for (const json& f : caps["features"]) ids.insert(f["id"].get<int>());
  EXPECT_EQ(ids, (std::set<int>{0, 1, 5, 9, 10, 11, 12, 20, 21, 22, 24, 25, 26, 31, 32, 33}));
  EXPECT_EQ(caps["spawn_formats"], json({"mjcf", "urdf"}));
}

}  // namespace
}  // namespace simgate::sim
