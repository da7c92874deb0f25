// simgate/recorder/recording_services.h — recording a running simulation: `simgate run
// --record FILE` from its first step, and the `simulation` component's services
// start_recording, stop_recording and get_recording_status for clients (docs/recording.md).
//
// One recording at a time. A client names a file, never a path: it is written in the
// directory the host allowed (`simgate run --record-dir DIR`; without one, recording over the
// wire is refused), so that no client can write elsewhere on the machine.
//
// Threads: start() under the simulation lock (a service, or the host before the loop runs);
// stop() without it (it waits for the file to be closed); stop_recording closes the file on a
// thread of its own and answers when it is closed.
#ifndef SIMGATE_RECORDER_RECORDING_SERVICES_H_
#define SIMGATE_RECORDER_RECORDING_SERVICES_H_

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "simgate/recorder/recorder.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

namespace simgate::recorder {

struct RecordingSetup {
  std::string dir;            // where clients' recordings go ("" : clients may not record)
  json deployment = nullptr;  // RecordingOptions::deployment
  std::vector<std::string> attachments;  // RecordingOptions::attachments
  mcap::Compression compression = mcap::Compression::zstd;
};

class RecordingServices : public std::enable_shared_from_this<RecordingServices> {
 public:
  RecordingServices(sim::Simulation& simulation, RecordingSetup setup);
  // stop() (without the simulation lock).
  ~RecordingServices();
  RecordingServices(const RecordingServices&) = delete;
  RecordingServices& operator=(const RecordingServices&) = delete;

  // Offers start_recording, stop_recording and get_recording_status on `simulation` (before
  // the transports register it).
  void add_to(sim::SupervisionServices& simulation);
  // Starts recording to `path` (any path: the host's). Under the simulation lock. Throws
  // ServiceError when a recording runs, std::runtime_error when the file cannot be created.
  void start(const std::string& path);
  // Ends the recording, if any, and waits for its file to be closed; returns its status
  // (null when none ran). Without the simulation lock.
  json stop();

 private:
  json status() const;  // under the simulation lock

  sim::Simulation& simulation_;
  RecordingSetup setup_;
  std::unique_ptr<Recorder> recorder_;  // under the simulation lock
  // Closes `recorder`'s file (detached) on a thread of its own, then calls `then` with its
  // status (stop_recording's answer); joins the threads of files closed before.
  void close_in_background(std::shared_ptr<Recorder> recorder, std::function<void(json)> then);

  struct Closing {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;  // the thread has finished its work
  };
  std::mutex closing_mutex_;      // guards closing_
  std::vector<Closing> closing_;  // files being closed (finished ones joined on the next)
};

}  // namespace simgate::recorder

#endif  // SIMGATE_RECORDER_RECORDING_SERVICES_H_
