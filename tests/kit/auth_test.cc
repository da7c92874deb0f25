// kit::TokenAuth: reading the "auth" option (the token from a file or the environment,
// never the config), who must present it, and the comparison.
#include "simgate/kit/auth.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "simgate/core/errors.h"

namespace simgate::kit {
namespace {

using ::testing::HasSubstr;
namespace ip = boost::asio::ip;

constexpr const char* k_token = "0123456789abcdef0123456789abcdef";

TokenAuth read_auth(const json& options, std::vector<std::string>* warnings = nullptr) {
  ConfigObject config(options, "");
  std::vector<std::string> ignored;
  TokenAuth auth = TokenAuth::read(config, warnings ? *warnings : ignored);
  config.finish();
  return auth;
}

std::string error_of(const json& options) {
  try {
    read_auth(options);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "no error";
}

struct TokenFile {
  std::filesystem::path path = std::filesystem::temp_directory_path() /
                               ("simgate-token-" + std::to_string(::getpid()) + "-" +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
  TokenFile(const std::string& content, mode_t mode) {
    std::ofstream(path) << content;
    ::chmod(path.c_str(), mode);
  }
  ~TokenFile() { std::filesystem::remove(path); }
};

TEST(TokenAuthTest, AbsentMeansOffForEveryPeer) {
  TokenAuth auth = read_auth(json::object());
  EXPECT_FALSE(auth.enabled);
  EXPECT_FALSE(auth.required_for(ip::make_address("192.0.2.7")));
  EXPECT_FALSE(auth.accepts(""));
}

TEST(TokenAuthTest, ReadsTheFirstLineOfTheTokenFile) {
  TokenFile file(std::string(k_token) + "\n", 0600);
  std::vector<std::string> warnings;
  TokenAuth auth = read_auth({{"auth", {{"token_file", file.path.string()}}}}, &warnings);
  EXPECT_TRUE(auth.enabled);
  EXPECT_TRUE(auth.accepts(k_token));
  EXPECT_FALSE(auth.accepts(std::string(k_token) + "\n"));
  EXPECT_TRUE(warnings.empty());
  EXPECT_EQ(auth.source, "file '" + file.path.string() + "'");
}

TEST(TokenAuthTest, ATokenFileOthersMayReadIsAWarning) {
  TokenFile file(k_token, 0644);
  std::vector<std::string> warnings;
  read_auth({{"auth", {{"token_file", file.path.string()}}}}, &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], HasSubstr("may be read by other users of this machine (chmod 600 it)"));
}

TEST(TokenAuthTest, ReadsTheEnvironmentVariable) {
  ::setenv("SIMGATE_AUTH_TEST_TOKEN", k_token, 1);
  TokenAuth auth = read_auth({{"auth", {{"token_env", "SIMGATE_AUTH_TEST_TOKEN"}}}});
  ::unsetenv("SIMGATE_AUTH_TEST_TOKEN");
  EXPECT_TRUE(auth.accepts(k_token));
  EXPECT_EQ(auth.source, "environment variable SIMGATE_AUTH_TEST_TOKEN");
}

TEST(TokenAuthTest, RefusesATokenWrittenInTheConfigWithoutRepeatingIt) {
  std::string error = error_of({{"auth", {{"token", k_token}}}});
  EXPECT_THAT(error, HasSubstr("auth.token: a token is never written in the config"));
  EXPECT_THAT(error, ::testing::Not(HasSubstr(k_token)));
}

TEST(TokenAuthTest, RefusesMissingAmbiguousWeakAndUnsendableTokens) {
  EXPECT_THAT(error_of({{"auth", json::object()}}),
              HasSubstr("auth: expected exactly one of \"token_file\""));
  EXPECT_THAT(error_of({{"auth", {{"token_file", "/x"}, {"token_env", "X"}}}}),
              HasSubstr("exactly one of"));
  EXPECT_THAT(error_of({{"auth", {{"token_file", "/nonexistent/token"}}}}),
              HasSubstr("auth.token_file: cannot read '/nonexistent/token'"));
  ::unsetenv("SIMGATE_AUTH_TEST_UNSET");
  EXPECT_THAT(
      error_of({{"auth", {{"token_env", "SIMGATE_AUTH_TEST_UNSET"}}}}),
      HasSubstr("auth.token_env: the environment variable SIMGATE_AUTH_TEST_UNSET is not set"));
  for (const char* weak :
       {"short", "has a space in it, long enough", "tab\there-and-long-enough"}) {
    ::setenv("SIMGATE_AUTH_TEST_TOKEN", weak, 1);
    EXPECT_THAT(error_of({{"auth", {{"token_env", "SIMGATE_AUTH_TEST_TOKEN"}}}}),
                HasSubstr("auth.token_env: "))
        << weak;
  }
  ::unsetenv("SIMGATE_AUTH_TEST_TOKEN");
  EXPECT_THAT(error_of({{"auth", {{"token_env", "X"}, {"loopbak", true}}}}), HasSubstr("loopbak"));
}

TEST(TokenAuthTest, LoopbackPeersAreTrustedUnlessAsked) {
  ::setenv("SIMGATE_AUTH_TEST_TOKEN", k_token, 1);
  TokenAuth remote_only = read_auth({{"auth", {{"token_env", "SIMGATE_AUTH_TEST_TOKEN"}}}});
  TokenAuth everyone =
      read_auth({{"auth", {{"token_env", "SIMGATE_AUTH_TEST_TOKEN"}, {"loopback", true}}}});
  ::unsetenv("SIMGATE_AUTH_TEST_TOKEN");
  for (const char* local : {"127.0.0.1", "127.3.2.1", "::1", "::ffff:127.0.0.1"}) {
    EXPECT_FALSE(remote_only.required_for(ip::make_address(local))) << local;
    EXPECT_TRUE(everyone.required_for(ip::make_address(local))) << local;
  }
  for (const char* remote : {"10.0.0.5", "192.0.2.1", "2001:db8::1", "::ffff:10.0.0.5", "0.0.0.0"})
    EXPECT_TRUE(remote_only.required_for(ip::make_address(remote))) << remote;
}

TEST(TokenAuthTest, AcceptsOnlyTheExactToken) {
  ::setenv("SIMGATE_AUTH_TEST_TOKEN", k_token, 1);
  TokenAuth auth = read_auth({{"auth", {{"token_env", "SIMGATE_AUTH_TEST_TOKEN"}}}});
  ::unsetenv("SIMGATE_AUTH_TEST_TOKEN");
  std::string token = k_token;
  EXPECT_TRUE(auth.accepts(token));
  EXPECT_FALSE(auth.accepts(""));
  EXPECT_FALSE(auth.accepts(token.substr(0, token.size() - 1)));
  EXPECT_FALSE(auth.accepts(token + "0"));
  for (std::size_t i = 0; i < token.size(); ++i) {
    std::string wrong = token;
    wrong[i] ^= 1;
    EXPECT_FALSE(auth.accepts(wrong)) << i;
  }
}

}  // namespace
}  // namespace simgate::kit
