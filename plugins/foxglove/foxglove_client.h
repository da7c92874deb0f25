// plugins/foxglove/foxglove_client.h — what the foxglove transport keeps of each connection
// (foxglove_server.h): the kit's WebSocket connection with its subscriptions, its parameter
// subscriptions and its client channels. The I/O thread's only.
#ifndef SIMGATE_PLUGINS_FOXGLOVE_FOXGLOVE_CLIENT_H_
#define SIMGATE_PLUGINS_FOXGLOVE_FOXGLOVE_CLIENT_H_

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "foxglove_server.h"
#include "simgate/core/streams.h"

namespace simgate::foxglove {

// A client: the kit's WebSocket connection and what the protocol keeps of it.
class FoxgloveServer::Client : public kit::WebSocketConnection {
 public:
  using WebSocketConnection::WebSocketConnection;
  struct Subscription {
    std::uint32_t channel_id = 0;
    Shape shape = Shape::sample;
    std::shared_ptr<StreamSubscription> stream{};  // null for the log channel
    SensorMessage message = SensorMessage::log;    // Shape::sensor: which message
    std::uint64_t scene_sent = ~std::uint64_t{0};  // the generation its last scene was of
  };
  std::map<std::uint32_t, Subscription> subscriptions;  // by the client's subscription id
  std::uint64_t time_told = 0;                          // the last Time message's time (ns)
  bool told_time = false;                               // a Time message was sent
  // the parameters it subscribed to (parametersSubscribe); all of them: `all_parameters`
  std::set<std::string> parameters;
  bool all_parameters = false;
  // its channels (clientPublish), by its id: the input stream each one's messages go to
  struct Publication {
    std::string component;
    std::vector<std::string> fields;
  };
  std::map<std::uint32_t, Publication> publications;
  // it sent a playback control request: it is told the playback's state from then on
  bool controls_playback = false;
};

}  // namespace simgate::foxglove

#endif  // SIMGATE_PLUGINS_FOXGLOVE_FOXGLOVE_CLIENT_H_
