#include "simgate/kit/auth.h"

#include <sys/stat.h>

#include <cstdlib>
#include <fstream>

#include "simgate/core/errors.h"

namespace simgate::kit {

namespace {

constexpr std::size_t k_min_token = 16;    // shorter is guessable
constexpr std::size_t k_max_token = 4096;  // a token, not a file's worth of bytes

// Refuses a token a client could not send on one line, or that is too short to resist guessing.
void check_token(const std::string& token, const std::string& path, const std::string& source) {
  if (token.size() < k_min_token)
    throw ConfigError(path + ": the token from " + source + " has " + std::to_string(token.size()) +
                      " characters; expected at least " + std::to_string(k_min_token) +
                      " (make one with `openssl rand -hex 32`)");
  if (token.size() > k_max_token)
    throw ConfigError(path + ": the token from " + source + " is longer than " +
                      std::to_string(k_max_token) + " characters");
  for (unsigned char c : token)
    if (c <= ' ' || c >= 0x7f)
      throw ConfigError(
          path + ": the token from " + source +
          " holds a space, a control or a non-ASCII character; expected printable ASCII only");
}

}  // namespace

TokenAuth TokenAuth::read(ConfigObject& config, std::vector<std::string>& warnings) {
  TokenAuth auth;
  auto object = config.get_object("auth");
  if (!object) return auth;
  ConfigObject& o = *object;
  if (o.has("token"))
    throw ConfigError(
        o.path_of("token") +
        ": a token is never written in the config (it is shared, checked in, printed); put it in "
        "a file (\"token_file\") or an environment variable (\"token_env\")");
  const bool from_file = o.has("token_file"), from_env = o.has("token_env");
  if (from_file == from_env)
    throw ConfigError(
        o.path() +
        ": expected exactly one of \"token_file\" (a path) or \"token_env\" (a variable name)");
  auth.enabled = true;
  auth.loopback = o.get_bool("loopback", false);
  const std::string key = from_file ? "token_file" : "token_env";
  const std::string where = o.required_string(key);
  o.finish();  // a misspelt key is the first thing to hear of
  if (from_file) {
    auth.source = "file '" + where + "'";
    std::ifstream in(where);
    if (!in) throw ConfigError(o.path_of(key) + ": cannot read '" + where + "'");
    std::getline(in, auth.token);
    if (!auth.token.empty() && auth.token.back() == '\r') auth.token.pop_back();
    struct stat st{};
    if (::stat(where.c_str(), &st) == 0 && (st.st_mode & (S_IRGRP | S_IROTH)))
      warnings.push_back(o.path_of(key) + ": '" + where +
                         "' may be read by other users of this machine (chmod 600 it)");
  } else {
    auth.source = "environment variable " + where;
    const char* value = std::getenv(where.c_str());
    if (!value || !*value)
      throw ConfigError(o.path_of(key) + ": the environment variable " + where +
                        " is not set (or empty)");
    auth.token = value;
  }
  check_token(auth.token, o.path_of(key), auth.source);
  return auth;
}

bool TokenAuth::accepts(std::string_view presented) const {
  if (!enabled || token.empty()) return false;
  // every byte compared, whatever differs first: the time says nothing of the token
  unsigned char diff = presented.size() == token.size() ? 0 : 1;
  for (std::size_t i = 0; i < presented.size(); ++i)
    diff |= static_cast<unsigned char>(presented[i]) ^
            static_cast<unsigned char>(token[i % token.size()]);
  return diff == 0;
}

bool TokenAuth::is_loopback(const boost::asio::ip::address& address) {
  if (address.is_v6() && address.to_v6().is_v4_mapped())
    return boost::asio::ip::make_address_v4(boost::asio::ip::v4_mapped, address.to_v6())
        .is_loopback();
  return address.is_loopback();
}

}  // namespace simgate::kit
