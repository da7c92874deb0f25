// catalog.cc — the foxglove transport's catalog: the channels of the streams it carries and
// the services it serves, advertised as they come and go (foxglove_server.h).
#include <algorithm>
#include <tuple>

#include <boost/asio/post.hpp>

#include "foxglove_client.h"

namespace simgate::foxglove {

namespace asio = boost::asio;

// ---- the catalog: channels and services

void FoxgloveServer::on_services_changed() {
  // under the simulation lock, any thread: only post
  if (catalog_wanted_.exchange(true, std::memory_order_acq_rel)) return;
  asio::post(io_, [this] { refresh_catalog(); });
}

void FoxgloveServer::refresh_catalog() {
  catalog_wanted_.store(false, std::memory_order_release);
  refresh_services();
  // the channels' schemas are made from a sample each, read under the simulation lock
  post([this] {
    std::vector<ChannelEntry> channels = read_channels();
    asio::post(io_, [this, channels = std::move(channels)]() mutable {
      apply_channels(std::move(channels));
    });
  });
}

std::vector<FoxgloveServer::ChannelEntry> FoxgloveServer::read_channels() const {
  // the log, always there
  std::vector<ChannelEntry> out(1);
  out[0].shape = Shape::log;
  out[0].channel.topic = k_log_topic;
  out[0].channel.schema_name = schema_name(SensorMessage::log);
  out[0].channel.schema = dump(sensor_schema(SensorMessage::log));
  if (!streams()) return out;
  for (const StreamInfo& info : streams()->streams(transport_name())) {
    if (info.direction != StreamDirection::out) continue;
    // a camera, a laser, an odometry, joints: in Foxglove's schemas, for its panels
    const std::vector<SensorChannel> sensor = sensor_channels(info.kind);
    for (const SensorChannel& c : sensor) {
      ChannelEntry entry;
      entry.component = info.component;
      entry.shape = Shape::sensor;
      entry.message = c.message;
      entry.channel.topic = topic_of(info.component) + std::string(c.suffix);
      entry.channel.schema_name = schema_name(c.message);
      entry.channel.schema = dump(sensor_schema(c.message));
      out.push_back(std::move(entry));
    }
    if (!sensor.empty()) continue;
    // any other: the component's samples as they are, described by a schema of one
    ChannelEntry entry;
    entry.component = info.component;
    entry.channel.topic = topic_of(info.component);
    entry.channel.schema_name = "simgate." + info.kind;
    json schema = json::object();
    if (auto sample = streams()->sample_now(info.component)) schema = schema_of(*sample);
    schema["title"] = entry.channel.schema_name;
    schema["description"] = info.component + ": " + info.type + " (" + info.kind + ")";
    entry.channel.schema = dump(schema);
    out.push_back(entry);
    if (info.kind == "body_poses") {
      // the simulation's bodies and geoms for the 3D panel, in Foxglove's schemas; another
      // world's as /w<k>/tf and /w<k>/scene
      const std::string prefix = "/" + world_prefix(info.component);
      for (const auto& [shape, topic, name, made] :
           {std::tuple{Shape::frame_transforms, "tf", k_frame_transforms,
                       frame_transforms_schema()},
            std::tuple{Shape::scene_update, "scene", k_scene_update, scene_update_schema()}}) {
        ChannelEntry derived;
        derived.component = info.component;
        derived.shape = shape;
        derived.channel.topic = prefix + topic;
        derived.channel.schema_name = name;
        derived.channel.schema = dump(made);
        out.push_back(std::move(derived));
      }
    }
  }
  return out;
}

void FoxgloveServer::apply_channels(std::vector<ChannelEntry> channels) {
  // ids: the same channel keeps its id (also across a removal and a return), another gets a
  // new one
  for (auto& entry : channels) {
    auto known = channel_history_.find(entry.channel.topic);
    if (known != channel_history_.end() && known->second.same_as(entry.channel)) {
      entry.channel.id = known->second.id;
    } else {
      entry.channel.id = next_channel_id_++;
      channel_history_[entry.channel.topic] = entry.channel;
    }
  }
  std::vector<std::uint32_t> gone;
  for (const auto& old : channels_)
    if (std::none_of(channels.begin(), channels.end(),
                     [&](const ChannelEntry& c) { return c.channel.id == old.channel.id; }))
      gone.push_back(old.channel.id);
  std::vector<Channel> added;
  for (const auto& entry : channels)
    if (std::none_of(channels_.begin(), channels_.end(),
                     [&](const ChannelEntry& c) { return c.channel.id == entry.channel.id; }))
      added.push_back(entry.channel);
  channels_ = std::move(channels);
  for (std::uint32_t id : gone) sensor_cache_.erase(id);
  // a scene goes with its /tf and /scene channels (its world deleted)
  std::erase_if(scenes_, [&](const auto& scene) {
    return std::none_of(channels_.begin(), channels_.end(), [&](const ChannelEntry& c) {
      return c.component == scene.first &&
             (c.shape == Shape::frame_transforms || c.shape == Shape::scene_update);
    });
  });
  // subscriptions to a channel that is gone end with it
  if (!gone.empty()) {
    for_each_connection([&](kit::Connection& connection) {
      Client& client = static_cast<Client&>(connection);
      for (auto it = client.subscriptions.begin(); it != client.subscriptions.end();) {
        if (std::find(gone.begin(), gone.end(), it->second.channel_id) == gone.end()) {
          ++it;
          continue;
        }
        if (it->second.stream) streams()->unsubscribe(it->second.stream);
        it = client.subscriptions.erase(it);
      }
    });
    broadcast(unadvertise(gone));
  }
  if (!added.empty()) broadcast(advertise(added));
  flush_touched();
}

void FoxgloveServer::refresh_services() {
  std::vector<ServiceDef> now;
  for (const ServiceDescriptor& d : descriptors()) {
    ServiceDef def;
    def.name = service_name_of(d.component, d.name);
    def.type = "simgate/" + d.qualified_name();
    def.request_schema = d.params_schema();
    def.response_schema = d.result_schema.is_object() ? d.result_schema : json::object();
    def.component = d.component;
    def.service = d.name;
    auto known = service_history_.find(def.name);
    if (known != service_history_.end() && known->second.same_as(def)) {
      def.id = known->second.id;
    } else {
      def.id = next_service_id_++;
      service_history_[def.name] = def;
    }
    now.push_back(std::move(def));
  }
  std::vector<std::uint32_t> gone;
  for (const auto& old : services_)
    if (std::none_of(now.begin(), now.end(), [&](const ServiceDef& s) { return s.id == old.id; }))
      gone.push_back(old.id);
  std::vector<ServiceDef> added;
  for (const auto& def : now)
    if (std::none_of(services_.begin(), services_.end(),
                     [&](const ServiceDef& s) { return s.id == def.id; }))
      added.push_back(def);
  services_ = std::move(now);
  if (!gone.empty()) broadcast(unadvertise_services(gone));
  if (!added.empty()) broadcast(advertise_services(added));
  flush_touched();
}

void FoxgloveServer::broadcast(const std::string& text) {
  for_each_connection([&](kit::Connection& connection) {
    auto& client = static_cast<Client&>(connection);
    if (client.open()) client.queue_text(text);
  });
}

}  // namespace simgate::foxglove
