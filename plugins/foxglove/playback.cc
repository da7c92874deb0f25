// playback.cc — the foxglove transport's playback control (foxglove_server.h): the Foxglove
// app's playback bar drives the simulation. Play and pause are `simulation play` / `pause`, the
// speed is `time set_time_scale`, and a seek backwards restores the newest of a ring of
// automatic snapshots (`simulation save_state` every rewind_interval_s simulated seconds, the
// last rewind_states kept) taken at or before the time sought. A served replay (`simgate replay
// --serve`, which serves `simulation seek` and `get_replay_status`) seeks in the recording
// instead: the bar spans the recording, and a seek goes to the recorded run's state at the time
// sought, forward or back.
#include <algorithm>
#include <cmath>

#include <boost/asio/post.hpp>

#include "foxglove_client.h"
#include "simgate/core/log.h"

namespace simgate::foxglove {

namespace asio = boost::asio;

// A playback request's calls under way: its answer (a Playback State to every client) goes
// once they have all answered.
struct FoxgloveServer::PlaybackRequest {
  std::weak_ptr<Client> client;  // who asked (told of what failed)
  std::string request_id;        // echoed in the Playback State
  bool did_seek = false;         // a restore_state is among the calls
  double seek_time = 0;          // the simulated time it restored (did_seek)
  std::size_t waiting = 0;       // calls not answered yet
  std::vector<std::string> failures;
};

bool FoxgloveServer::serves(std::string_view component, std::string_view service) const {
  return std::any_of(services_.begin(), services_.end(), [&](const ServiceDef& s) {
    return s.component == component && s.service == service;
  });
}

bool FoxgloveServer::playback_offered() const {
  return serves("simulation", "play") && serves("simulation", "pause") &&
         serves("time", "set_time_scale");
}

bool FoxgloveServer::seek_offered() const {
  return serves("simulation", "seek") && serves("simulation", "get_replay_status");
}

void FoxgloveServer::ask_replay_range() {
  if (!seek_offered()) return;
  replay_status_call_ = new_request_id();
  run_or_submit(replay_status_call_, Call{"simulation", "get_replay_status", json::object()});
}

bool FoxgloveServer::rewind_offered() const {
  return settings_.rewind_interval_s > 0 && settings_.time_hz > 0 && !seek_offered() &&
         serves("simulation", "save_state") && serves("simulation", "restore_state");
}

double FoxgloveServer::simulated_time() {
  const double now = streams() ? streams()->time() : 0;
  if (seek_hold_ && seek_hold_->first == now) return seek_hold_->second;
  seek_hold_.reset();
  return now;
}

std::pair<std::uint64_t, std::uint64_t> FoxgloveServer::playback_range() {
  if (replay_range_)
    return {to_nanoseconds(replay_range_->first), to_nanoseconds(replay_range_->second)};
  const double now = simulated_time();
  const double start = rewinds_.empty() ? now : rewinds_.front().time;
  return {to_nanoseconds(start), to_nanoseconds(now + k_playback_horizon_s)};
}

void FoxgloveServer::take_rewind_snapshot() {
  // the I/O thread, on a time tick: one snapshot per rewind_interval_s of simulated time
  if (rewind_call_ != 0 || !streams() || !rewind_offered()) return;
  const double now = simulated_time();
  if (!rewinds_.empty() && now < rewinds_.back().time + settings_.rewind_interval_s) return;
  rewind_call_ = new_request_id();
  run_or_submit(rewind_call_, Call{"simulation", "save_state", json::object()});
}

void FoxgloveServer::drop_rewind(std::uint64_t handle) {
  // called from a completion, which may run inside run_or_submit with the simulation lock held
  // by this thread: the call waits for the I/O thread's next turn. Its answer is nobody's
  // (on_service_completion ignores an id it does not know).
  asio::post(io_, [this, handle] {
    if (!stopping_)
      run_or_submit(new_request_id(), Call{"simulation", "drop_state", json{{"handle", handle}}});
  });
}

void FoxgloveServer::control_playback(Client& client, const PlaybackControlRequest& request) {
  if (!playback_offered()) {
    complain(client, Level::error,
             "playback control needs simulation play and pause and time set_time_scale served "
             "by this transport");
    return;
  }
  client.controls_playback = true;
  auto pending = std::make_shared<PlaybackRequest>();
  pending->client = std::static_pointer_cast<Client>(client.shared_from_this());
  pending->request_id = std::string(request.request_id);
  std::vector<std::pair<RequestId, Call>> calls;
  const double now = simulated_time();
  if (request.seek_ns) {
    const double sought = static_cast<double>(*request.seek_ns) / 1e9;
    if (seek_offered()) {
      // a served replay: anywhere in the recording (the answer says where it went)
      pending->did_seek = true;
      pending->seek_time = sought;
      calls.emplace_back(new_request_id(),
                         Call{"simulation", "seek", json{{"sim_time", std::max(0.0, sought)}}});
    } else if (!rewind_offered()) {
      complain(client, Level::warning,
               "seek: this transport keeps no snapshots to rewind to (rewind_interval_s is 0, "
               "or simulation save_state and restore_state are not served here)");
    } else if (sought > now) {
      complain(client, Level::warning,
               "seek: the simulation has not reached " + std::to_string(sought) +
                   " s yet (it is at " + std::to_string(now) +
                   " s); play, faster if need be, to get there");
    } else if (rewinds_.empty()) {
      complain(client, Level::warning, "seek: no snapshot taken yet to rewind to");
    } else {
      // the newest snapshot at or before the time sought (the oldest when it is older)
      auto it = std::find_if(rewinds_.rbegin(), rewinds_.rend(),
                             [&](const Rewind& r) { return r.time <= sought + 1e-9; });
      const Rewind target = it == rewinds_.rend() ? rewinds_.front() : *it;
      if (target.time > sought + 1e-9)
        complain(client, Level::warning,
                 "seek: the oldest snapshot kept is at " + std::to_string(target.time) +
                     " s (rewind_states " + std::to_string(settings_.rewind_states) + " every " +
                     std::to_string(settings_.rewind_interval_s) + " s)");
      pending->did_seek = true;
      pending->seek_time = target.time;
      calls.emplace_back(new_request_id(),
                         Call{"simulation", "restore_state", json{{"handle", target.handle}}});
    }
  }
  // the speed every time: another client (or the config) may have set another time scale
  if (request.speed > 0 && std::isfinite(request.speed))
    calls.emplace_back(new_request_id(),
                       Call{"time", "set_time_scale", json{{"value", request.speed}}});
  calls.emplace_back(new_request_id(),
                     Call{"simulation", request.play ? "play" : "pause", json::object()});
  playing_ = request.play;
  if (request.speed > 0 && std::isfinite(request.speed)) speed_ = request.speed;
  pending->waiting = calls.size();
  for (auto& [id, call] : calls) {
    call.client = client.number();
    playback_calls_[id] = pending;
  }
  run_or_submit(std::move(calls));
}

bool FoxgloveServer::playback_completion(RequestId id, Outcome& outcome) {
  if (id == replay_status_call_) {
    replay_status_call_ = 0;
    if (outcome.status == Status::success && outcome.value && outcome.value->is_object())
      replay_range_ =
          std::pair{outcome.value->value("start_time", 0.0), outcome.value->value("end_time", 0.0)};
    return true;
  }
  if (id == rewind_call_) {
    rewind_call_ = 0;
    if (outcome.status == Status::success && outcome.value && outcome.value->is_number_integer()) {
      rewinds_.push_back(Rewind{outcome.value->get<std::uint64_t>(), simulated_time()});
      while (rewinds_.size() > settings_.rewind_states) {
        drop_rewind(rewinds_.front().handle);
        rewinds_.pop_front();
      }
    }
    return true;
  }
  const auto it = playback_calls_.find(id);
  if (it == playback_calls_.end()) return false;
  const std::shared_ptr<PlaybackRequest> pending = it->second;
  playback_calls_.erase(it);
  if (outcome.status != Status::success)
    pending->failures.push_back(std::string(to_string(outcome.status)) +
                                (outcome.message.empty() ? "" : ": " + outcome.message));
  else if (outcome.value && outcome.value->is_object() && outcome.value->contains("sim_time"))
    pending->seek_time = outcome.value->value("sim_time", pending->seek_time);  // restore_state's
  if (--pending->waiting > 0) return true;
  if (pending->did_seek && pending->failures.empty()) {
    // the states taken after the time restored belong to a future that will not happen now
    while (!rewinds_.empty() && rewinds_.back().time > pending->seek_time + 1e-9) {
      drop_rewind(rewinds_.back().handle);
      rewinds_.pop_back();
    }
    // a paused simulation takes no step that would tell the streams its time: until it does,
    // the time told is the one restored
    if (streams()) seek_hold_ = std::pair{streams()->time(), pending->seek_time};
  }
  if (!pending->failures.empty())
    if (auto client = pending->client.lock(); client && !client->closed())
      complain(*client, Level::error, "playback control: " + join(pending->failures));
  const std::uint64_t now = to_nanoseconds(simulated_time());
  // to every client that controls playback (one that never sent a request may not know the
  // message: @foxglove/ws-protocol 0.8 throws on an opcode it does not know)
  // a served replay at the end of its recording has ended (it serves the last state, paused)
  const bool ended = replay_range_ && simulated_time() >= replay_range_->second - 1e-9;
  const std::string state = playback_state(ended      ? PlaybackStatus::ended
                                           : playing_ ? PlaybackStatus::playing
                                                      : PlaybackStatus::paused,
                                           now, speed_, pending->did_seek, pending->request_id);
  for_each_connection([&](kit::Connection& connection) {
    auto& client = static_cast<Client&>(connection);
    if (client.open() && client.controls_playback) client.queue_binary(state);
  });
  flush_touched();
  return true;
}

}  // namespace simgate::foxglove
