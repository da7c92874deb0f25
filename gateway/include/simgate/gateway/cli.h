// simgate/gateway/cli.h — the `simgate` command line.
//
//   simgate run CONFIG [--log-level L] [--realtime-factor F|max] [--endpoints-file PATH]
//                      [--plugin-path DIR]
//   simgate check CONFIG [--plugin-path DIR]
//   simgate call [--transport T] [--host H] [--port P] [--timeout S] COMPONENT SERVICE [ARGS...]
//   simgate list [--transport T] [--host H] [--port P] [--timeout S]
//   simgate --help | --version
//
// Exit codes: 0 success; 1 a failed call or a runtime error; 2 bad usage or an invalid
// configuration. `run` shuts down cleanly on SIGINT/SIGTERM (a second signal exits at once).
#ifndef SIMGATE_GATEWAY_CLI_H_
#define SIMGATE_GATEWAY_CLI_H_

namespace simgate::gateway {

int run_cli(int argc, char** argv);

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_CLI_H_
