// simgate/gateway/cli.h — the `simgate` command line.
//
//   simgate run CONFIG [--status [SECONDS]] [--log-level L] [--realtime-factor F|max]
//                      [--endpoints-file PATH] [--plugin-path DIR]...
//   simgate check CONFIG [--log-level L] [--plugin-path DIR]...
//   simgate call [CLIENT OPTIONS] COMPONENT SERVICE [ARGS...]
//   simgate list [CLIENT OPTIONS] [--json]
//   simgate help [COMMAND] | --help | --version       (every command has --help and --version)
//   CLIENT OPTIONS: --transport socket|jsonrpc|websocket|dds, --host H, --port P, --domain N,
//                   --partition P, --dds-config XML, --timeout S
//
// Parsed with CLI11; docs/cli.md is the reference. Options of `call` come before COMPONENT:
// everything after it is taken as ARGS, even words that look like options (-1, --x).
//
// Exit codes: 0 success; 1 a failed call or a runtime error; 2 bad usage or an invalid
// configuration. `run` shuts down cleanly on SIGINT/SIGTERM (a second signal exits at once).
#ifndef SIMGATE_GATEWAY_CLI_H_
#define SIMGATE_GATEWAY_CLI_H_

#include <stdexcept>
#include <string>
#include <vector>

#include "simgate/core/status.h"

namespace simgate::gateway {

// A command line that cannot be run as written (exit code 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Runs the command line; returns the process exit code. Prints to stdout and stderr.
int run_cli(int argc, char** argv);

// The params of `simgate call COMPONENT SERVICE ARGS...`. Each ARG is JSON (5, "text", [1,2],
// {"a": 1}) or else a bare word, taken as a string; an ARG that is not JSON and contains '='
// is a named argument `name=value` (name an identifier, value JSON or a bare word). All
// named -> a JSON object; none named -> a JSON array (empty when there are no ARGS). A
// leading "--" is skipped. Throws UsageError when named and positional ARGS are mixed, a
// name is repeated or is not an identifier (a string containing '=' is written JSON-quoted).
json call_params(const std::vector<std::string>& args);

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_CLI_H_
