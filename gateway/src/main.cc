// simgate: the gateway executable (see simgate/gateway/cli.h).
#include "simgate/gateway/cli.h"

int main(int argc, char** argv) { return simgate::gateway::run_cli(argc, argv); }
