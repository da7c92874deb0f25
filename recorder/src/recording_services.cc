#include "simgate/recorder/recording_services.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <utility>

#include "simgate/core/errors.h"
#include "simgate/core/log.h"

namespace simgate::recorder {

namespace {

// A client's file name: letters, digits, '_', '-' and '.', not starting with '.'; ".mcap" is
// added when it does not end so.
std::string checked_file_name(const std::string& name) {
  const bool ok =
      !name.empty() && name.size() <= 200 && name.front() != '.' &&
      std::all_of(name.begin(), name.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
      });
  if (!ok)
    throw ServiceError("simulation start_recording: name '" + name +
                           "' is not a file name: expected letters, digits, '_', '-' and '.' "
                           "(not first), at most 200 (the file goes in the host's recording "
                           "directory)",
                       Failure::bad_arguments, {{"parameter", "name"}});
  return name.ends_with(".mcap") ? name : name + ".mcap";
}

}  // namespace

RecordingServices::RecordingServices(sim::Simulation& simulation, RecordingSetup setup)
    : simulation_(simulation), setup_(std::move(setup)) {}

RecordingServices::~RecordingServices() {
  try {
    stop();
  } catch (const std::exception& e) {
    log::error("recording: ", e.what());
  }
  std::lock_guard lock(closing_mutex_);
  for (auto& c : closing_) c.thread.join();
}

void RecordingServices::close_in_background(std::shared_ptr<Recorder> recorder,
                                            std::function<void(json)> then) {
  std::lock_guard lock(closing_mutex_);
  // the threads of files closed before: joined now (they have ended), not kept till the end
  std::erase_if(closing_, [](Closing& c) {
    if (!c.done->load(std::memory_order_acquire)) return false;
    c.thread.join();
    return true;
  });
  auto done = std::make_shared<std::atomic<bool>>(false);
  closing_.push_back({std::thread([recorder = std::move(recorder), then = std::move(then), done] {
                        json status = recorder->finish();
                        if (then) then(std::move(status));
                        done->store(true, std::memory_order_release);
                      }),
                      done});
}

void RecordingServices::start(const std::string& path) {
  if (recorder_ && recorder_->error().empty())
    throw ServiceError("simulation start_recording: already recording to " + recorder_->path() +
                           " (simulation stop_recording first)",
                       Failure::service_error, {{"recording", recorder_->path()}});
  if (recorder_) {
    // one that stopped on its own (an error): its file is closed before the next starts
    recorder_->detach();
    close_in_background(std::move(recorder_), nullptr);
  }
  RecordingOptions options;
  options.path = path;
  options.compression = setup_.compression;
  options.deployment = setup_.deployment;
  options.attachments = setup_.attachments;
  recorder_ = std::make_unique<Recorder>(simulation_, std::move(options));
}

json RecordingServices::stop() {
  std::unique_ptr<Recorder> recorder;
  {
    std::lock_guard lock(*simulation_.gate());
    if (!recorder_) return nullptr;
    recorder_->detach();
    recorder = std::move(recorder_);
  }
  return recorder->finish();
}

json RecordingServices::status() const {
  if (!recorder_) return {{"recording", false}};
  return recorder_->status();
}

void RecordingServices::add_to(sim::SupervisionServices& simulation) {
  std::weak_ptr<RecordingServices> weak = weak_from_this();
  simulation
      .offer_service(
          "start_recording",
          [weak](const std::string& name) {
            auto self = weak.lock();
            if (!self) throw ServiceError("simulation start_recording: the host is stopping");
            if (self->setup_.dir.empty())
              throw ServiceError(
                  "simulation start_recording: recording over the wire is off (start simgate "
                  "run with --record-dir DIR to let clients record into DIR)",
                  Failure::service_error);
            const std::string path =
                (std::filesystem::path(self->setup_.dir) / checked_file_name(name)).string();
            try {
              self->start(path);
            } catch (const ServiceError&) {
              throw;
            } catch (const std::exception& e) {
              throw ServiceError("simulation start_recording: " + std::string(e.what()));
            }
            return self->status();
          },
          {"name"})
      .not_replayed()
      .doc(
          "Record the run from now to NAME.mcap in the host's recording directory: inputs, "
          "outcomes, state hashes, streams (docs/recording.md); returns the recording's status");
  simulation
      .offer_async_service("stop_recording",
                           [weak](Completion done) {
                             auto self = weak.lock();
                             if (!self || !self->recorder_)
                               throw ServiceError("simulation stop_recording: no recording runs",
                                                  Failure::service_error);
                             // the inputs stop here; the file is closed off the simulation lock, then the answer
                             self->recorder_->detach();
                             self->close_in_background(
                                 std::move(self->recorder_),
                                 [done](json status) { done(Status::success, std::move(status)); });
                           })
      .concurrent()
      .not_replayed()
      .doc(
          "End the recording and close its file; returns its status (steps, inputs, samples, "
          "bytes)");
  simulation
      .offer_service("get_recording_status",
                     [weak] {
                       auto self = weak.lock();
                       return self ? self->status() : json{{"recording", false}};
                     })
      .not_replayed()
      .doc("{recording, path, steps, inputs, samples, samples_dropped, bytes, error}");
}

}  // namespace simgate::recorder
