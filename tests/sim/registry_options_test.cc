// SimRegistryOptions (issue #37 item 4): a built-in type declares its options in one place
// (SIMGATE_BUILTIN_TYPE in its own file); the deployment's JSON Schema and the docs are
// checked against those declarations, an undeclared option is refused naming the declared
// ones, and a type that reads an option it does not declare is caught.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <set>
#include <string>

#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
std::string source(const std::string& relative) {
  return std::string(SIMGATE_SOURCE_DIR) + "/" + relative;
}

TEST(SimRegistryOptions, EveryBuiltInTypeDeclaresItsOptionsAndItsPage) {
  const ComponentRegistry registry = builtin_registry();
  std::set<std::string> names;
  for (const auto& [name, type] : registry.types()) {
    names.insert(name);
    EXPECT_TRUE(type.options_declared) << name;
    EXPECT_FALSE(type.doc_page.empty()) << name;
    EXPECT_FALSE(read_file(source(type.doc_page)).empty()) << name << ": " << type.doc_page;
    for (const OptionSpec& o : type.options) {
      EXPECT_FALSE(o.doc.empty()) << name << "." << o.name;
      EXPECT_TRUE(o.schema.is_object() && !o.schema.empty()) << name << "." << o.name;
    }
  }
  for (const char* expected :
       {"ground_robot", "human", "robot", "mjcf", "motion_vw", "waypoint", "teleport", "pose",
        "actuators", "sensors", "armature", "armature_pose", "imu", "odometry", "laser_scanner",
        "proximity", "video_camera", "depth_camera"})
    EXPECT_TRUE(names.count(expected)) << expected << " is not registered";
}

// before: the schema's option lists were written by hand beside the code's; `mjcf` had none
TEST(SimRegistryOptions, TheDeploymentSchemaIsTheDeclarationsOfTheBuiltIns) {
  const ComponentRegistry registry = builtin_registry();
  const std::string path = source("config/schema/deployment.schema.json");
  json schema = json::parse(read_file(path));
  const json robots = registry.options_schema(Kind::robot);
  const json components = registry.options_schema(Kind::component);
  const bool same = schema["$defs"]["robot"]["allOf"] == robots &&
                    schema["$defs"]["component"]["allOf"] == components;
  if (!same) {
    // what the file should hold, for the developer to copy over it
    schema["$defs"]["robot"]["allOf"] = robots;
    schema["$defs"]["component"]["allOf"] = components;
    const std::string generated = std::string(SIMGATE_BINARY_DIR) + "/deployment.schema.json";
    std::ofstream(generated) << schema.dump(2) << "\n";
    ADD_FAILURE() << path
                  << ": its robot and component option rules differ from the types' declarations "
                  << "(SIMGATE_BUILTIN_TYPE); the file with the declared rules is " << generated;
  }
  // the type lists the schema describes name every built-in type
  for (const auto& [name, type] : registry.types()) {
    const char* def = type.kind == Kind::robot ? "robot" : "component";
    EXPECT_THAT(schema["$defs"][def]["properties"]["type"]["description"].get<std::string>(),
                HasSubstr(name))
        << def << ".type's description does not name " << name;
  }
}

// The row of `name` in configuration.md's table of types (the first cell names it).
std::string table_row(const std::string& page, const std::string& name) {
  std::size_t at = page.find("| type | kind | options | services |");
  if (at == std::string::npos) return "";
  while ((at = page.find("\n| ", at)) != std::string::npos) {
    const std::size_t end = page.find('\n', at + 1);
    const std::string row = page.substr(at + 1, end - at - 1);
    const std::string first = row.substr(0, row.find(" | ", 2));
    if (first.find("`" + name + "`") != std::string::npos) return row;
    at = end;
  }
  return "";
}

// before: the table had no `mjcf` row, nothing checked its option lists
TEST(SimRegistryOptions, TheDocsNameEveryDeclaredOption) {
  const ComponentRegistry registry = builtin_registry();
  const std::string configuration = read_file(source("docs/configuration.md"));
  for (const auto& [name, type] : registry.types()) {
    const std::string row = table_row(configuration, name);
    ASSERT_FALSE(row.empty()) << "docs/configuration.md's table of types has no row for " << name;
    const std::string page = read_file(source(type.doc_page));
    for (const OptionSpec& o : type.options) {
      EXPECT_THAT(row, HasSubstr("`" + o.name + "`")) << "docs/configuration.md, row " << name;
      EXPECT_THAT(page, HasSubstr("`" + o.name + "`"))
          << type.doc_page << " does not document " << name << "." << o.name;
    }
    if (type.options.empty()) {
      EXPECT_THAT(row, HasSubstr("| — |")) << name << " takes no options";
    }
  }
}

class SimRegistryOptionsTest : public ::testing::Test {
 protected:
  SimRegistryOptionsTest()
      : sim_(Model::load_file(testing::demo_scene()), SimulationOptions{std::nullopt, 0.0}) {}
  Simulation sim_;
};

TEST_F(SimRegistryOptionsTest, AnUndeclaredOptionIsRefusedNamingTheDeclaredOnes) {
  ComponentRegistry registry = builtin_registry();
  try {
    registry.create(Kind::robot, {"robot", "ground_robot", "robot", "robots[0]"},
                    json{{"wheel_radus", 0.1}}, sim_, nullptr);
    FAIL() << "an undeclared option was accepted";
  } catch (const ConfigError& e) {
    EXPECT_THAT(
        e.what(),
        HasSubstr("robots[0].options.wheel_radus: unknown key (did you mean 'wheel_radius'?"));
    EXPECT_THAT(e.what(), HasSubstr("max_wheel_speed"));  // declared, though not given
  }
}

TEST_F(SimRegistryOptionsTest, ATypeThatReadsAnOptionItDoesNotDeclareIsCaught) {
  ComponentRegistry registry = builtin_registry();
  struct Sneaky : SimComponent {
    explicit Sneaky(ComponentContext& c) : SimComponent(c.name(), c.sim()) {
      (void)c.options().get_number("gain", 1, 0, 2);
    }
  };
  registry.add(builtin_type<Sneaky>("sneaky", Kind::robot, "reads an undeclared option",
                                    "docs/configuration.md", {}));
  EXPECT_THROW(registry.create(Kind::robot, {"robot", "sneaky", "robot", "robots[0]"},
                               json::object(), sim_, nullptr),
               std::logic_error);
}

}  // namespace
}  // namespace simgate::sim
