// Loading transport plugins with dlopen: the mock plugin drives the core; broken plugins
// are refused with messages naming the plugin, the path, the reason and the paths tried.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>

#include "plugins/mock_transport.h"
#include "simgate/core/errors.h"
#include "simgate/core/plugin_loader.h"

namespace simgate {
namespace {

using ::testing::HasSubstr;

const std::string kDir = SIMGATE_TEST_BROKEN_PLUGIN_DIR;

std::string path_of(const std::string& name) {
  return kDir + "/libsimgate_transport_" + name + ".so";
}

std::string load_error(const std::string& name_or_path) {
  try {
    load_transport_plugin(name_or_path);
  } catch (const PluginError& e) {
    return e.what();
  }
  return "loaded";
}

int add(int a, int b) { return a + b; }

TEST(PluginLoaderTest, MockPluginDrivesTheCore) {
  auto plugin = load_transport_plugin(path_of("mock"));
  EXPECT_EQ(plugin->name(), "mock");
  EXPECT_STREQ(plugin->descriptor().version, "1.2.3");
  auto rm = plugin->create(json{{"greeting", "hi"}}, "transports.mock");
  auto* mock = static_cast<testing::MockTransport*>(rm.get());
  EXPECT_EQ(rm->name(), "Mock service manager");
  EXPECT_EQ(rm->endpoints(), std::vector<std::string>{"mock://hi"});
  rm->register_service("test_component", add, "add", {"a", "b"});
  auto id = mock->client_call("test_component", "add", json{1, 2});
  rm->process();
  EXPECT_TRUE(mock->started());
  ASSERT_TRUE(mock->client_outcome(id));
  EXPECT_EQ(mock->client_outcome(id)->value, json(3));
}

TEST(PluginLoaderTest, FoundThroughSimgatePluginPath) {
  ::setenv("SIMGATE_PLUGIN_PATH", ("/nonexistent:" + kDir).c_str(), 1);
  auto plugin = load_transport_plugin("mock");
  EXPECT_EQ(plugin->path(), path_of("mock"));
}

TEST(PluginLoaderTest, NotFoundListsEveryPathTried) {
  ::setenv("SIMGATE_PLUGIN_PATH", "/nonexistent/a:/nonexistent/b", 1);
  std::string e = load_error("teleportation");
  EXPECT_THAT(e, HasSubstr("transport plugin 'teleportation'"));
  EXPECT_THAT(e, HasSubstr("/nonexistent/a/libsimgate_transport_teleportation.so"));
  EXPECT_THAT(e, HasSubstr("/nonexistent/b/libsimgate_transport_teleportation.so"));
  EXPECT_THAT(e, HasSubstr(std::string(SIMGATE_TEST_PLUGIN_DIR) +
                           "/libsimgate_transport_teleportation.so"));
  EXPECT_THAT(e, HasSubstr("SIMGATE_PLUGIN_PATH"));
}

TEST(PluginLoaderTest, UnknownOptionKeysAreRefusedBeforeCreate) {
  auto plugin = load_transport_plugin(path_of("mock"));
  try {
    plugin->create(json{{"greting", "hi"}}, "transports.mock.options");
    FAIL() << "accepted an unknown key";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("transports.mock.options.greting: unknown key (did you mean "
                                    "'greeting'? known keys: greeting)"));
  }
}

TEST(PluginLoaderTest, WrongAbiVersionIsRefused) {
  std::string e = load_error(path_of("badabi"));
  EXPECT_THAT(e, HasSubstr("transport plugin 'badabi' (" + path_of("badabi") + ")"));
  EXPECT_THAT(e,
              HasSubstr("ABI version 999, expected " + std::to_string(SIMGATE_PLUGIN_ABI_VERSION)));
}

// before: the page showed "ABI version 0, expected 1" while the code was at 8
TEST(PluginLoaderTest, TheRefusalTheDocsShowNamesTheCodesAbiVersion) {
  std::ifstream in(std::string(SIMGATE_SOURCE_DIR) + "/docs/writing-a-transport.md");
  const std::string page((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const unsigned abi = SIMGATE_PLUGIN_ABI_VERSION;
  EXPECT_THAT(page, HasSubstr("ABI version " + std::to_string(abi - 1) + ", expected " +
                              std::to_string(abi) + " (rebuild the plugin against this simgate)"));
}

TEST(PluginLoaderTest, WrongBuildTagIsRefused) {
  EXPECT_THAT(load_error(path_of("badtag")),
              HasSubstr("built with 'abi1;cxx11abi=0;json=2.0', expected"));
}

TEST(PluginLoaderTest, MissingEntrySymbolIsRefused) {
  std::string e = load_error(path_of("nosymbol"));
  EXPECT_THAT(e, HasSubstr("entry function simgate_transport_nosymbol_entry not found"));
}

TEST(PluginLoaderTest, MissingRequiredFunctionIsRefused) {
  EXPECT_THAT(load_error(path_of("nocreate")), HasSubstr("required function create is missing"));
}

TEST(PluginLoaderTest, DescriptorNameMustMatch) {
  EXPECT_THAT(load_error(path_of("misnamed")),
              HasSubstr("calls itself 'other', expected 'misnamed'"));
}

TEST(PluginLoaderTest, UnresolvedSymbolsFailAtDlopen) {
  std::string e = load_error(path_of("undefined"));
  EXPECT_THAT(e, HasSubstr("dlopen failed"));
  EXPECT_THAT(e, HasSubstr("simgate_function_nobody_defines"));
}

TEST(PluginLoaderTest, ThrowingConstructorIsReportedNotPropagated) {
  auto plugin = load_transport_plugin(path_of("throws"));
  try {
    plugin->create(json::object(), "transports.throws");
    FAIL() << "created a manager whose constructor throws";
  } catch (const TransportError& e) {
    // its options are valid (it has no validate_options): a failure to start, not a config error
    EXPECT_THAT(e.what(), HasSubstr("transports.throws: transport 'throws' could not start: "
                                    "cannot open /dev/imaginary: no such device"));
  }
}

TEST(PluginLoaderTest, NotASharedLibraryIsRefused) {
  std::string e = load_error(std::string(SIMGATE_SOURCE_DIR) + "/README.md.so");
  EXPECT_THAT(e, HasSubstr("found; paths tried"));
  std::string text = load_error(std::string(SIMGATE_SOURCE_DIR) + "/tests/core/plugins/broken.cc");
  EXPECT_THAT(text, HasSubstr("dlopen failed"));
}

}  // namespace
}  // namespace simgate
