// The DDS transport's settings: what the loopback settings expose (sockets), its options
// (unknown keys, bad values, endpoints), and the Cyclone settings checked before it starts
// (simgate check).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cyclone_config.h"
#include "dds_transport_fixture.h"

namespace simgate::dds::test {
namespace {

// The inodes of this process's sockets.
std::set<std::string> socket_inodes() {
  std::set<std::string> out;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/fd")) {
    std::error_code ec;
    std::string target = std::filesystem::read_symlink(entry.path(), ec).string();
    if (!ec && target.rfind("socket:[", 0) == 0) out.insert(target.substr(8, target.size() - 9));
  }
  return out;
}

// "address:port" of the sockets of /proc/net/<table> whose inode is in `inodes`.
std::vector<std::string> bound(const std::string& table, const std::set<std::string>& inodes) {
  std::vector<std::string> out;
  std::ifstream in("/proc/net/" + table);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string slot, local, remote, state, queues, timer, retransmits, uid, timeout, inode;
    fields >> slot >> local >> remote >> state >> queues >> timer >> retransmits >> uid >>
        timeout >> inode;
    if (!inodes.count(inode)) continue;
    // IPv4 "0100007F:1F90": the address in host byte order (little-endian here), the port
    auto colon = local.find(':');
    std::string address = local.substr(0, colon);
    if (address.size() == 8) {
      unsigned long a = std::stoul(address, nullptr, 16);
      address = std::to_string(a & 0xff) + "." + std::to_string(a >> 8 & 0xff) + "." +
                std::to_string(a >> 16 & 0xff) + "." + std::to_string(a >> 24);
    }
    out.push_back(address + ":" + std::to_string(std::stoul(local.substr(colon + 1), nullptr, 16)));
  }
  return out;
}

// Item 9: Cyclone 0.10 binds its receive sockets to the wildcard address whatever interface it
// is given (ddsi_udp.c: unicast and multicast receive sockets bind INADDR_ANY; no setting
// changes it), so the loopback settings cannot keep them off other interfaces.
// docs/transports/dds.md says exactly what that exposes; this checks it is all there is: per
// participant, two UDP ports on 0.0.0.0 (discovery 7410 + 250 d + 2 i, data one above), one
// transmit socket on 127.0.0.1; no multicast port (7400 + 250 d), no TCP, no IPv6.
TEST(DdsExposure, LoopbackSettingsOpenTwoWildcardUdpPortsAndALoopbackOne) {
  const std::set<std::string> before = socket_inodes();
  auto rm = load_transport(k_plugin, server_options(test_partition()));
  std::set<std::string> ours;
  for (const std::string& inode : socket_inodes())
    if (!before.count(inode)) ours.insert(inode);
  std::vector<std::string> udp = bound("udp", ours);
  EXPECT_EQ(bound("tcp", ours), std::vector<std::string>{});
  EXPECT_EQ(bound("udp6", ours), std::vector<std::string>{});
  EXPECT_EQ(bound("tcp6", ours), std::vector<std::string>{});
  ASSERT_EQ(udp.size(), 3u) << ::testing::PrintToString(udp);
  std::vector<unsigned> wildcard;
  for (const std::string& socket : udp) {
    std::string address = socket.substr(0, socket.find(':'));
    unsigned port = static_cast<unsigned>(std::stoul(socket.substr(socket.find(':') + 1)));
    if (address == "0.0.0.0")
      wildcard.push_back(port);
    else
      EXPECT_EQ(address, "127.0.0.1") << socket;
  }
  ASSERT_EQ(wildcard.size(), 2u) << ::testing::PrintToString(udp);
  std::sort(wildcard.begin(), wildcard.end());
  const unsigned base = 7400 + 250 * test_domain();
  EXPECT_EQ((wildcard[0] - (base + 10)) % 2, 0u) << wildcard[0];  // discovery: 7410 + 250 d + 2 i
  EXPECT_LE(wildcard[0], base + 10 + 2 * 60);                     // i <= MaxAutoParticipantIndex
  EXPECT_EQ(wildcard[1], wildcard[0] + 1);                        // data
}

TEST(DdsTransportConfig, UnknownKeysAndBadValuesAreRejectedWithTheirName) {
  auto expect_error = [](json options, const std::string& needle) {
    try {
      load_transport(k_plugin, options);
      ADD_FAILURE() << "accepted " << options.dump();
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  std::string loopback = loopback_uri();
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"bogus", 1}}, "bogus");
  expect_error({{"domain", 999}, {"config", loopback}}, "domain");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"partition", "sim*"}},
               "partition");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"global_policy", "maybe"}},
               "global_policy");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"stream_writes", "sometimes"}},
               "stream_writes");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"max_depth", 1}}, "max_depth");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"max_depth", 10001}},
               "max_depth");
  expect_error(
      {{"domain", test_domain()}, {"config", "<CycloneDDS><Domain><General><NoSuchSetting/>"}},
      "domain");
}

// ---- the Cyclone settings are checked before the transport starts (simgate check) ----

// The loopback settings, as XML text (config/dds/loopback.xml).
std::string loopback_xml() {
  std::ifstream in(SIMGATE_LOOPBACK_DDS_XML);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Loopback settings with `extra` inside their <Domain> element.
std::string loopback_with(const std::string& extra) {
  std::string xml = loopback_xml();
  xml.insert(xml.find("</Domain>"), extra);
  return xml;
}

// What check_cyclone_config() says of `config` on this process's test domain ("" = nothing).
std::string settings_error(const std::string& config) {
  try {
    check_cyclone_config(test_domain(), config);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(DdsSettingsCheck, SettingsCycloneAcceptsPass) {
  EXPECT_EQ(settings_error(""), "");                        // the compiled-in loopback settings
  EXPECT_EQ(settings_error(loopback_uri()), "");            // a file:// URI
  EXPECT_EQ(settings_error(SIMGATE_LOOPBACK_DDS_XML), "");  // a plain file name
  EXPECT_EQ(settings_error(loopback_xml()), "");            // XML text
  // two fragments; an element Cyclone closes at the end of the text itself
  EXPECT_EQ(
      settings_error(loopback_xml() + ",<CycloneDDS><Domain><Discovery><ParticipantIndex>auto"),
      "");
}

TEST(DdsSettingsCheck, SettingsCycloneRefusesAreAConfigErrorWithCyclonesReason) {
  const std::string expected =
      "config: expected Cyclone DDS settings (XML, file names or file:// URIs) that Cyclone "
      "accepts for domain " +
      std::to_string(test_domain()) + ", found settings it refuses: ";
  // XML its parser cannot read
  EXPECT_THAT(
      settings_error("<CycloneDDS><Domain></General></Domain></CycloneDDS>"),
      ::testing::StartsWith(expected +
                            "//CycloneDDS/Domain: parser error open/close tag mismatch (General)"));
  // an element that does not exist, in a later fragment too
  EXPECT_THAT(settings_error(loopback_with("<Bogus/>")),
              ::testing::StartsWith(expected + "//CycloneDDS/Domain: Bogus: unknown element"));
  EXPECT_THAT(settings_error(loopback_xml() + ",<CycloneDDS><Domain><Discovery><Bogus/>"),
              ::testing::HasSubstr("//CycloneDDS/Domain/Discovery: Bogus: unknown element"));
  // a misspelt one, with the name meant (Cyclone's setting names, from its installed header)
  EXPECT_THAT(
      settings_error(
          loopback_with("<Discovery><ParticipantIndx>auto</ParticipantIndx></Discovery>")),
      ::testing::HasSubstr("ParticipantIndx: unknown element (did you mean 'ParticipantIndex'?)"));
  // a value out of its set
  EXPECT_THAT(settings_error(loopback_with(
                  "<Discovery><ParticipantIndex>some</ParticipantIndex></Discovery>")),
              ::testing::HasSubstr("ParticipantIndex"));
  // a file that does not open
  EXPECT_EQ(settings_error("file:///nonexistent/cyclone.xml"),
            expected + "can't open configuration file file:///nonexistent/cyclone.xml");
  // an interface this machine does not have
  std::string absent = loopback_xml();
  absent.replace(absent.find("name=\"lo\""), 9, "name=\"nosuchif0\"");
  EXPECT_EQ(settings_error(absent), expected + "nosuchif0: does not match an available interface.");
}

TEST(DdsSettingsCheck, CheckingWritesNoTraceFile) {
  // Cyclone opens a trace file before its interface lookup: the check sends tracing to stderr
  // (and drops it) instead
  std::string trace =
      ::testing::TempDir() + "simgate-settings-check-" + std::to_string(getpid()) + ".log";
  std::remove(trace.c_str());
  std::string settings = loopback_with("<Tracing><Verbosity>finest</Verbosity><OutputFile>" +
                                       trace + "</OutputFile></Tracing>");
  EXPECT_EQ(settings_error(settings), "");
  EXPECT_FALSE(std::ifstream(trace).good()) << trace << " was written";
  EXPECT_THAT(settings_error(settings + ",<CycloneDDS><Domain><Bogus/>"),
              ::testing::HasSubstr("Bogus"));
  EXPECT_FALSE(std::ifstream(trace).good()) << trace << " was written";
}

TEST(DdsSettingsCheck, EnvMeansTheSettingsOfCycloneddsUri) {
  // ctest sets CYCLONEDDS_URI to the loopback file for every test
  const char* uri = std::getenv("CYCLONEDDS_URI");
  ASSERT_NE(uri, nullptr);
  EXPECT_STREQ(resolve_config("env"),
               uri);  // was nullptr, which dds_create_domain() reads as Cyclone's defaults
  EXPECT_EQ(settings_error("env"), "");
  std::string saved = uri;
  ::setenv("CYCLONEDDS_URI", "<CycloneDDS><Domain><Bogus/></Domain></CycloneDDS>", 1);
  EXPECT_THAT(settings_error("env"), ::testing::HasSubstr("Bogus: unknown element"));
  ::setenv("CYCLONEDDS_URI", saved.c_str(), 1);
}

TEST(DdsSettingsCheck, TheTransportStartsOnTheDomainItsSettingsWereCheckedOn) {
  // the check creates and deletes the domain: nothing of it is left to the transport
  auto plugin = load_transport_plugin(k_plugin, {});
  json options = server_options(test_partition());
  options["config"] = loopback_xml();
  EXPECT_NO_THROW(plugin->validate(options, "transports.dds.options"));
  auto rm = plugin->create(options, "transports.dds.options");
  ASSERT_NE(rm, nullptr);
  // once the process has the domain, its settings prevail: others are not checked (and
  // would not apply)
  EXPECT_EQ(settings_error(loopback_with("<Bogus/>")), "");
}

TEST(DdsSettingsCheck, ThePluginsValidateNamesTheOptionsPath) {
  auto plugin = load_transport_plugin(k_plugin, {});
  json options = {{"domain", test_domain()}, {"config", loopback_with("<Bogus/>")}};
  try {
    plugin->validate(options, "transports.dds.options");
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr(
                              "transports.dds.options.config: expected Cyclone DDS settings"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("Bogus: unknown element"));
  }
  options = {{"domain", 300}};
  EXPECT_THROW(plugin->validate(options, "transports.dds.options"), ConfigError);
}

TEST(DdsTransportConfig, EndpointsNameDomainAndPartition) {
  auto rm = load_transport(k_plugin, server_options(test_partition()));
  auto endpoints = rm->endpoints();
  ASSERT_EQ(endpoints.size(), 1u);
  EXPECT_EQ(endpoints[0],
            "dds:domain=" + std::to_string(test_domain()) + ";partition=" + test_partition());
}

}  // namespace
}  // namespace simgate::dds::test
