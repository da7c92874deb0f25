// SimExample: the component library of docs/writing-a-component.md
// (docs/examples/odometer_library.cc, built as libsimgate_components_odometer.so), loaded
// with dlopen as a config's "component_libraries" is, so the documentation cannot rot. An
// odometer measures the distance its robot travelled: sync `get_distance`, async
// `wait_distance d` (completes once the robot has travelled d more metres; interruptible).
// Also: what loading a component library checks (ComponentLibraryTest).
#include <fstream>
#include <sstream>

#include "sim_fixture.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/sim/component_library.h"

// ---- its tests ---------------------------------------------------------------------------
namespace simgate::sim {
namespace {

const std::string k_example_dir = SIMGATE_EXAMPLE_PLUGIN_DIR;

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class SimExampleTest : public testing::DemoSim {
 protected:
  void SetUp() override {
    DemoSim::SetUp();
    registry_ = builtin_registry();
    EXPECT_EQ(load_component_library(registry_, "odometer", {k_example_dir}),
              std::vector<std::string>{"odometer"});
    auto* robot = static_cast<Robot*>(sim_->find("robot")->component.get());
    auto odometer =
        registry_.create(Kind::component, {"robot.odometer", "odometer", "robot", "test"},
                         json{{"min_step", 0.001}}, *sim_, robot);
    rm_->register_component(*odometer);
    sim_->add_component(std::move(odometer), "odometer", "robot");
  }
  void TearDown() override {
    DemoSim::TearDown();  // the components go before the library their code is in
    registry_ = ComponentRegistry{};
  }

  ComponentRegistry registry_;  // holds the loaded library
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
  for (json bad : {json(-1.0), json(std::nan("")), json(1e300)})
    EXPECT_EQ(call("robot.odometer", "wait_distance", {bad}).value,
              json("distance must be positive and at most 1e6 m"));
}

TEST_F(SimExampleTest, ItsPropertyIsSettable) {
  EXPECT_EQ(call("robot.odometer", "get_properties").value,
            json({{"properties", {{"min_step", 0.001}}}}));
  EXPECT_EQ(call("robot.odometer", "set_property", {"min_step", 0.01}).status, Status::success);
  EXPECT_EQ(call("robot.odometer", "get_configurations").value->at("configurations")["type"],
            "odometer");
}

TEST(ComponentLibraryTest, TheDocShowsTheLibraryVerbatim) {
  const std::string code =
      read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/examples/odometer_library.cc");
  const std::string page =
      read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/writing-a-component.md");
  ASSERT_FALSE(code.empty());
  EXPECT_NE(page.find("```cpp\n" + code + "```"), std::string::npos)
      << "docs/writing-a-component.md must show docs/examples/odometer_library.cc verbatim";
}

TEST(ComponentLibraryTest, TheBuiltInsComeThroughTheSameDescriptor) {
  ComponentRegistry registry = builtin_registry();
  ASSERT_NE(registry.find("pose"), nullptr);
  EXPECT_EQ(registry.find("pose")->origin, "built in");
  // a second registration of the built-ins is refused: no library replaces a type
  try {
    add_component_library(registry, builtin_component_library(), "the built-in component types",
                          "built in");
    FAIL() << "registered twice";
  } catch (const PluginError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("which built in already provides"));
  }
}

TEST(ComponentLibraryTest, ALibraryMayNotReplaceAType) {
  ComponentRegistry registry = builtin_registry();
  registry.add<PlainRobot>("odometer", Kind::component, "someone else's odometer");
  try {
    load_component_library(registry, "odometer", {k_example_dir});
    FAIL() << "loaded";
  } catch (const PluginError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("component library 'odometer' ("));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("it registers type 'odometer', which"));
  }
  EXPECT_EQ(registry.find("odometer")->doc, "someone else's odometer");  // nothing was added
}

TEST(ComponentLibraryTest, AMissingLibraryListsThePathsTried) {
  ComponentRegistry registry;
  try {
    load_component_library(registry, "no_such_library", {"/nonexistent/dir"});
    FAIL() << "loaded";
  } catch (const PluginError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr(
                              "component library 'no_such_library': no "
                              "libsimgate_components_no_such_library.so found; paths tried:"));
    EXPECT_THAT(e.what(),
                ::testing::HasSubstr("/nonexistent/dir/libsimgate_components_no_such_library.so"));
  }
}

TEST(ComponentLibraryTest, ATransportPluginIsNotAComponentLibrary) {
  // the socket transport, given by path: no simgate_components_..._entry in it
  ComponentRegistry registry;
  try {
    load_component_library(
        registry, std::string(SIMGATE_TEST_PLUGIN_DIR) + "/libsimgate_transport_socket.so");
    FAIL() << "loaded";
  } catch (const PluginError& e) {
    EXPECT_THAT(e.what(),
                ::testing::HasSubstr(
                    "entry function simgate_components_libsimgate_transport_socket_entry"));
  }
}

}  // namespace
}  // namespace simgate::sim
