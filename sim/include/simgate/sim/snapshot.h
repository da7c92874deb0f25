// simgate/sim/snapshot.h — a picture of the whole scene (issue #22): the async service
// `simulation get_snapshot camera width height` (docs/world/snapshot.md) and the offline
// `simgate snapshot --config` share the Snapshotter.
//
// The view: an MJCF <camera> of the scene by name (its pose and field of view), or, by
// default, a free view framing the whole scene: it looks at the centre of the box around
// every visible geom but planes (each geom's own box, at its current place;
// MuJoCo's <statistic> center and extent when there are only planes) from the azimuth
// k_free_azimuth and the elevation k_free_elevation, as MuJoCo's free camera looks, and
// from the nearest distance at which every corner of that box is in the image (times
// k_free_margin), with the model's <visual><global fovy>.
// MuJoCo's own free camera stands 1.5 extents away; the extent counts floor planes, which
// would make a small robot on a large floor a few pixels.
//
// Threads: start() and take() on the simulation thread under the simulation lock (the
// scene is copied there, never rendered there); the render thread renders and encodes and
// calls `done`.
#ifndef SIMGATE_SIM_SNAPSHOT_H_
#define SIMGATE_SIM_SNAPSHOT_H_

#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>
#include <functional>
#include <memory>
#include <string>

#include "simgate/sim/render_support.h"
#include "simgate/sim/renderer.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

namespace simgate::sim {

struct SnapshotOptions {
  static constexpr long long k_default_width = 640, k_default_height = 480;  // pixels
  static constexpr long long k_max_size = 8192;                              // pixels, either side
  // pixels in all: an image is rendered (4x multisampled) and read back whole; 4096 x 4096
  // takes about 1 GB while it is made (llvmpipe), and the renderer keeps its largest buffer
  static constexpr long long k_max_pixels = 4096LL * 4096;
  // an MJCF camera's name; "" (or "free" when no camera has that name): the free view
  std::string camera;
  long long width = k_default_width;
  long long height = k_default_height;
};

// The free view's angles (degrees) and the margin around the scene's sphere.
constexpr double k_free_azimuth = 135, k_free_elevation = -25, k_free_margin = 1.08;

// Where the scene is: the box (world axes, m) the free view frames.
struct Framing {
  double low[3] = {-1, -1, -1};
  double high[3] = {1, 1, 1};
};
Framing frame_scene(const mjModel* m, const mjData* d);

// The free view of (m, d): the whole scene, `width` x `height` pixels.
CameraView free_view(const mjModel* m, const mjData* d, int width, int height);

class Snapshotter {
 public:
  using Done = std::function<void(Status, json)>;  // the image record, or the reason it failed

  explicit Snapshotter(Simulation& sim) : sim_(sim) {}

  // Snapshots queued or rendering at once, at most, not counting those whose request ended
  // (skipped when their turn comes): more are refused, so that one client's batch of large
  // snapshots cannot hold the renderer (and every camera) for minutes.
  static constexpr std::size_t k_max_in_flight = 8;

  // Checks the options (ServiceError naming the parameter: bad_arguments), copies the
  // scene of the current state and queues its render; `done` runs on the render thread
  // with the record: rgb_image_record's fields plus `camera` (the name, or "free") and
  // `view` {position, forward, up, fovy}. ServiceError when nothing can be rendered, or
  // k_max_in_flight snapshots are under way. `wanted` (Renderer::render): asked when the
  // render's turn comes; false skips it (the request ended: its client left).
  void start(const SnapshotOptions& options, Done done, std::function<bool()> wanted = {});
  // start() and wait (bounded) for the record; ServiceError when it failed. For a caller
  // that is the only thread of its simulation (the offline `simgate snapshot`).
  json take(const SnapshotOptions& options, std::chrono::milliseconds timeout);

 private:
  // The view the options ask for (checked), and the camera's name for the record.
  CameraView view(const SnapshotOptions& options, std::string& camera) const;
  Renderer& renderer();
  std::unique_ptr<SceneCopy> scene(const CameraView& view);

  Simulation& sim_;
  std::shared_ptr<Renderer> renderer_;  // null until the first snapshot
  // The snapshots queued or rendering, each with its `wanted` (the render thread's
  // callbacks take theirs out).
  struct InFlight {
    std::mutex mutex;
    std::map<std::uint64_t, std::function<bool()>> wanted;  // by ticket
    std::uint64_t next_ticket = 0;
    std::size_t still_wanted();  // those whose request has not ended
  };
  std::shared_ptr<InFlight> in_flight_ = std::make_shared<InFlight>();
  RenderModelCopy model_copy_;  // the renderer's copy of the current model
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SNAPSHOT_H_
