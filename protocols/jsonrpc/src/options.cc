// options.cc — the options of the JSON-RPC transports (simgate/jsonrpc/engine.h: Options).
#include "simgate/jsonrpc/engine.h"
#include "simgate/core/config.h"

namespace simgate::jsonrpc {

Options Options::parse(const json& options, std::string_view transport, std::uint16_t port) {
  ConfigObject config(options.is_null() ? json::object() : options, "");
  kit::TcpOptions defaults;
  defaults.port = port;
  defaults.max_message_bytes = 8u << 20;
  defaults.max_unsent_bytes = 16u << 20;
  defaults.max_connections = 512;
  defaults.max_in_flight = 1024;
  Options o;
  o.tcp = kit::TcpOptions::read(config, defaults, transport);
  o.max_depth = static_cast<std::size_t>(
      config.get_int("max_depth", static_cast<long long>(o.max_depth), 2, 10000));
  o.stream_queue = static_cast<std::size_t>(
      config.get_int("stream_queue", static_cast<long long>(o.stream_queue), 1, 100000));
  o.tcp.finish(config);
  return o;
}

}  // namespace simgate::jsonrpc
