// streams.cc — the foxglove transport's streams (foxglove_server.h): subscriptions, the
// samples as Message Data (as they are, or in Foxglove's schemas: scene.h, sensors.h), the
// log's lines, the Time messages, and the clients' own channels (clientPublish).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include <boost/asio/post.hpp>

#include "foxglove_client.h"
#include "simgate/core/log.h"
#include "simgate/core/streams.h"
#include "simgate/core/text.h"

namespace simgate::foxglove {

namespace asio = boost::asio;

// ---- subscriptions

void FoxgloveServer::subscribe(Client& client, const Subscribe& request) {
  for (const auto& [id, channel_id] : request.subscriptions) {
    if (client.subscriptions.count(id)) {
      complain(client, Level::error,
               "subscription id " + std::to_string(id) +
                   " is in use on this connection (unsubscribe it first, or pick another)");
      continue;
    }
    const auto entry = std::find_if(channels_.begin(), channels_.end(), [&](const ChannelEntry& c) {
      return c.channel.id == channel_id;
    });
    if (entry != channels_.end() && entry->shape == Shape::log) {
      client.subscriptions[id] = Client::Subscription{channel_id, Shape::log};
      // the last lines first, then each as it comes
      for (const auto& [time, text] : log_backlog_) queue_message(client, id, time, text);
      continue;
    }
    std::shared_ptr<StreamSubscription> stream;
    if (entry != channels_.end() && streams()) {
      // images: the newest only, a slow client never gets a backlog of them
      const bool image =
          entry->shape == Shape::sensor && (entry->message == SensorMessage::compressed_image ||
                                            entry->message == SensorMessage::raw_image ||
                                            entry->message == SensorMessage::camera_calibration);
      stream = streams()->subscribe(
          entry->component, transport_name(),
          SubscriberOptions{image ? 1 : settings_.stream_queue, "foxglove " + client.label(),
                            [this] { wake_streams(); }});
    }
    if (!stream) {
      std::vector<std::string> ids;
      for (const auto& c : channels_)
        ids.push_back(std::to_string(c.channel.id) + " " + c.channel.topic);
      complain(client, Level::error,
               "subscribe: no channel " + std::to_string(channel_id) +
                   " (channels: " + (ids.empty() ? std::string("none") : join(ids)) + ")");
      continue;
    }
    client.subscriptions[id] =
        Client::Subscription{channel_id, entry->shape, std::move(stream), entry->message};
  }
}

void FoxgloveServer::unsubscribe(Client& client, const Unsubscribe& request) {
  for (std::uint32_t id : request.subscription_ids) {
    auto it = client.subscriptions.find(id);
    if (it == client.subscriptions.end()) {
      complain(client, Level::warning,
               "unsubscribe: no subscription " + std::to_string(id) + " on this connection");
      continue;
    }
    if (it->second.stream) streams()->unsubscribe(it->second.stream);
    client.subscriptions.erase(it);
  }
}

// ---- client publishing: commands for input streams

void FoxgloveServer::advertise_publications(Client& client, const ClientAdvertise& request) {
  for (const ClientChannel& channel : request.channels) {
    const std::string component = component_of(channel.topic);
    const auto info = streams() ? streams()->find(component, transport_name()) : std::nullopt;
    if (channel.encoding != "json") {
      complain(client, Level::error,
               "advertise: channel " + std::to_string(channel.id) + " (" +
                   quoted_prefix(channel.topic) + ") is encoded " +
                   quoted_prefix(channel.encoding, 40) +
                   ": this server takes json (serverInfo's supportedEncodings)");
    } else if (!info || info->direction != StreamDirection::in) {
      std::vector<std::string> inputs;
      if (streams())
        for (const auto& s : streams()->streams(transport_name()))
          if (s.direction == StreamDirection::in)
            inputs.push_back(topic_of(s.component) + " {" + join(s.fields) + "}");
      complain(
          client, Level::error,
          "advertise: no input stream at " + quoted_prefix(channel.topic) + " on this transport (" +
              (inputs.empty() ? std::string("it takes none") : "it takes " + join(inputs)) + ")");
    } else {
      client.publications[channel.id] = Client::Publication{component, info->fields};
    }
  }
}

void FoxgloveServer::publish(Client& client, const ClientMessageData& message) {
  const auto it = client.publications.find(message.channel_id);
  if (it == client.publications.end()) {
    complain(client, Level::error,
             "a message on client channel " + std::to_string(message.channel_id) +
                 ", which this connection has not advertised (or the server refused)");
    return;
  }
  const auto command = read_command(message.payload, it->second.fields);
  if (!command) {
    complain(client, Level::error,
             "a message for " + topic_of(it->second.component) +
                 " is not a JSON object: " + quoted_prefix(message.payload, 60));
    return;
  }
  const PublishResult result = streams()->publish(it->second.component, transport_name(), *command);
  if (!result.ok)
    complain(client, Level::error, topic_of(it->second.component) + ": " + result.error);
}

void FoxgloveServer::wake_streams() {
  if (streams_woken_.exchange(true, std::memory_order_acq_rel)) return;
  asio::post(io_, [this] { drain_streams(); });
}

void FoxgloveServer::drain_streams() {
  streams_woken_.store(false, std::memory_order_release);
  for_each_connection([this](kit::Connection& connection) {
    Client& client = static_cast<Client&>(connection);
    std::uint64_t latest = 0;
    for (auto it = client.subscriptions.begin(); it != client.subscriptions.end();) {
      auto& [id, sub] = *it;
      if (!sub.stream) {  // the log's: drain_log sends its lines
        ++it;
        continue;
      }
      samples_.clear();
      sub.stream->take(samples_);
      std::uint64_t lost = 0;
      const ChannelEntry* entry = nullptr;  // a converted channel's (sensor, /tf, /scene)
      if (sub.shape != Shape::sample) {
        const auto found = std::find_if(channels_.begin(), channels_.end(), [&](const auto& c) {
          return c.channel.id == sub.channel_id;
        });
        if (found != channels_.end()) entry = &*found;
      }
      for (const SamplePtr& sample : samples_) {
        latest = std::max(latest, to_nanoseconds(sample->time()));
        std::string converted;
        const std::string* text = &converted;
        if (sub.shape == Shape::sample) {
          text = &sample->text();
        } else if (entry && sub.shape == Shape::sensor) {
          text = &convert_sensor(*entry, *sample);
        } else if (entry) {
          converted = convert(*entry, *sample, sub.scene_sent);
        }
        if (text->empty()) continue;
        if (!queue_message(client, id, sample->time(), *text)) ++lost;
      }
      sub.stream->note_dropped(lost);
      if (sub.stream->closed()) {
        // its component is gone: the channel is unadvertised with the catalog's refresh
        it = client.subscriptions.erase(it);
        continue;
      }
      ++it;
    }
    if (latest > 0) send_time(client, latest);
  });
  samples_.clear();
  for (auto& [component, scene] : scenes_)
    if (std::exchange(scene.wanted, false)) request_geometry(component, scene);
  flush_touched();
}

std::string FoxgloveServer::convert(const ChannelEntry& entry, const StreamSample& sample,
                                    std::uint64_t& scene_sent) {
  Scene& scene = scenes_[entry.component];  // its world's
  const json& poses = sample.data();
  const std::uint64_t generation =
      poses.is_object() ? poses.value("generation", std::uint64_t{0}) : 0;
  if (!scene.frames.known() || scene.frames.generation != generation) {
    // the model changed (or its scene is not known yet): its scene first
    scene.wanted = !scene.refused;
    return {};
  }
  if (entry.shape == Shape::frame_transforms) return frame_transforms(poses, scene.frames);
  if (scene_sent == generation) return {};  // the entities stay until the model changes
  scene_sent = generation;
  return scene_update(scene.geometry, scene.frames);
}

const std::string& FoxgloveServer::convert_sensor(const ChannelEntry& entry,
                                                  const StreamSample& sample) {
  SensorCache& cache = sensor_cache_[entry.channel.id];
  if (cache.seq == sample.seq()) return cache.text;
  cache.seq = sample.seq();
  cache.text = sensor_message(entry.message, sample, entry.component, cache.arc);
  if (cache.text.empty())
    log::debug(name(), ": ", entry.channel.topic, ": sample ", sample.seq(), " is not of ",
               entry.channel.schema_name, "'s shape; skipped");
  return cache.text;
}

bool FoxgloveServer::queue_message(Client& client, std::uint32_t subscription, double time,
                                   const std::string& text) {
  const std::uint64_t ns = to_nanoseconds(time);
  return client.queue_droppable_with([&](std::string& out) {
    kit::WebSocketConnection::append_frame_head(out, kit::FrameParser::k_binary,
                                                k_message_data_head_bytes + text.size());
    append_message_data_head(out, subscription, ns);
    out += text;
  });
}

void FoxgloveServer::log_line(log::Level level, std::string_view text) {
  // any thread, under the logger's lock: keep it, wake the I/O thread
  const double time = streams() ? streams()->time() : 0;
  {
    std::lock_guard lock(log_mutex_);
    if (log_incoming_.size() >= k_log_backlog) log_incoming_.erase(log_incoming_.begin());
    log_incoming_.emplace_back(time, log_message(time, level, text));
  }
  if (log_woken_.exchange(true, std::memory_order_acq_rel)) return;
  asio::post(io_, [this] { drain_log(); });
}

void FoxgloveServer::drain_log() {
  log_woken_.store(false, std::memory_order_release);
  std::vector<std::pair<double, std::string>> lines;
  {
    std::lock_guard lock(log_mutex_);
    lines.swap(log_incoming_);
  }
  for_each_connection([&](kit::Connection& connection) {
    Client& client = static_cast<Client&>(connection);
    for (const auto& [id, sub] : client.subscriptions)
      if (sub.shape == Shape::log)
        for (const auto& [time, text] : lines) queue_message(client, id, time, text);
  });
  for (auto& line : lines) {
    if (log_backlog_.size() >= k_log_backlog) log_backlog_.pop_front();
    log_backlog_.push_back(std::move(line));
  }
  flush_touched();
}

void FoxgloveServer::request_geometry(const std::string& component, Scene& scene) {
  if (scene.call != 0) return;
  scene.call = new_request_id();
  run_or_submit(scene.call, Call{component, "get_scene_geometry", json{{"include_meshes", true}}});
}

std::string FoxgloveServer::world_prefix(std::string_view component) {
  const auto world = RequestManager::world_address(component);
  return world ? std::string(component.substr(0, world->second)) : std::string();
}

void FoxgloveServer::send_time(Client& client, std::uint64_t time_ns) {
  if (client.told_time && client.time_told == time_ns) return;
  client.told_time = true;
  client.time_told = time_ns;
  client.queue_binary(time_message(time_ns));
}

void FoxgloveServer::tick_time() {
  if (stopping_ || settings_.time_hz <= 0 || !streams()) return;
  // simulated time between samples: paused, it stays; stepped, it jumps
  const std::uint64_t now = to_nanoseconds(simulated_time());
  take_rewind_snapshot();
  if (now > 0) {
    for_each_connection([&](kit::Connection& connection) {
      auto& client = static_cast<Client&>(connection);
      if (client.open()) send_time(client, now);
    });
    flush_touched();
  }
  // the subscribed parameters are read again about once a second
  if (++ticks_ % static_cast<std::uint32_t>(std::max(1.0, settings_.time_hz)) == 0)
    poll_parameters();
  time_timer_.expires_after(std::chrono::microseconds(std::llround(1e6 / settings_.time_hz)));
  time_timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) tick_time();
  });
}

}  // namespace simgate::foxglove
