// `simulation get_snapshot` and the Snapshotter behind it (snapshot.h,
// docs/world/snapshot.md): a picture of the scene from an MJCF camera or from a free view
// that frames it all.
#include "simgate/sim/snapshot.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <limits>

#include "simgate/core/errors.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {

namespace {

constexpr const char* k_who = "simulation get_snapshot";

void check_size(const char* parameter, long long value) {
  if (value >= 1 && value <= SnapshotOptions::k_max_size) return;
  throw ServiceError(std::string(k_who) + ": " + parameter + " is the image's " + parameter +
                         " in pixels, an integer from 1 to " +
                         std::to_string(SnapshotOptions::k_max_size) + ", found " +
                         std::to_string(value),
                     Failure::bad_arguments, {{"parameter", parameter}});
}

json view_json(const CameraView& v) {
  return {{"position", {v.position[0], v.position[1], v.position[2]}},
          {"forward", {v.forward[0], v.forward[1], v.forward[2]}},
          {"up", {v.up[0], v.up[1], v.up[2]}},
          {"fovy", v.fovy}};
}

// Half the size of geom g along its own axes (its bounding sphere's radius on each axis
// for the shapes whose size says less: meshes, height fields).
void local_half_size(const mjModel* m, int g, double half[3]) {
  const mjtNum* size = m->geom_size + 3 * g;
  switch (m->geom_type[g]) {
    case mjGEOM_SPHERE: half[0] = half[1] = half[2] = size[0]; return;
    case mjGEOM_CAPSULE:
      half[0] = half[1] = size[0];
      half[2] = size[1] + size[0];
      return;
    case mjGEOM_CYLINDER:
      half[0] = half[1] = size[0];
      half[2] = size[1];
      return;
    case mjGEOM_ELLIPSOID:
    case mjGEOM_BOX:
      half[0] = size[0];
      half[1] = size[1];
      half[2] = size[2];
      return;
    default: half[0] = half[1] = half[2] = m->geom_rbound[g]; return;
  }
}

}  // namespace

Framing frame_scene(const mjModel* m, const mjData* d) {
  // the box around every visible geom of finite size, at its current place
  double low[3], high[3];
  bool any = false;
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->geom_type[g] == mjGEOM_PLANE || m->geom_rgba[4 * g + 3] == 0 || m->geom_group[g] > 2)
      continue;
    if (!(m->geom_rbound[g] > 0) || !std::isfinite(m->geom_rbound[g])) continue;
    double half[3];
    local_half_size(m, g, half);
    const mjtNum* r =
        d->geom_xmat + 9 * g;  // row-major: world axis i = sum_j r[3i + j] * local axis j
    for (int i = 0; i < 3; ++i) {
      const double reach = std::abs(r[3 * i]) * half[0] + std::abs(r[3 * i + 1]) * half[1] +
                           std::abs(r[3 * i + 2]) * half[2];
      const double c = d->geom_xpos[3 * g + i];
      low[i] = any ? std::min(low[i], c - reach) : c - reach;
      high[i] = any ? std::max(high[i], c + reach) : c + reach;
    }
    any = true;
  }
  Framing f;
  if (!any) {  // only planes: MuJoCo's own statistics
    const double half = m->stat.extent > 0 ? m->stat.extent / 2 : 1.0;
    for (int i = 0; i < 3; ++i) {
      f.low[i] = m->stat.center[i] - half;
      f.high[i] = m->stat.center[i] + half;
    }
    return f;
  }
  for (int i = 0; i < 3; ++i) {
    f.low[i] = low[i];
    f.high[i] = high[i];
  }
  return f;
}

CameraView free_view(const mjModel* m, const mjData* d, int width, int height) {
  CameraView v;
  v.width = width;
  v.height = height;
  v.fovy = m->vis.global.fovy;
  const Framing f = frame_scene(m, d);
  const double az = k_free_azimuth * M_PI / 180, el = k_free_elevation * M_PI / 180;
  const double forward[3] = {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                             std::sin(el)};
  const double up[3] = {-std::sin(el) * std::cos(az), -std::sin(el) * std::sin(az), std::cos(el)};
  const double right[3] = {forward[1] * up[2] - forward[2] * up[1],
                           forward[2] * up[0] - forward[0] * up[2],
                           forward[0] * up[1] - forward[1] * up[0]};
  double center[3];
  for (int i = 0; i < 3; ++i) center[i] = (f.low[i] + f.high[i]) / 2;
  // the nearest distance from which every corner of the box is inside both fields of view
  const double tan_y = std::tan(v.fovy * M_PI / 360), tan_x = tan_y * width / height;
  double distance = 0, nearest = std::numeric_limits<double>::infinity(), farthest = 0;
  double depth[8];
  for (int corner = 0; corner < 8; ++corner) {
    double q[3];
    for (int i = 0; i < 3; ++i) q[i] = ((corner >> i) & 1 ? f.high[i] : f.low[i]) - center[i];
    const double x = q[0] * right[0] + q[1] * right[1] + q[2] * right[2];
    const double y = q[0] * up[0] + q[1] * up[1] + q[2] * up[2];
    depth[corner] = q[0] * forward[0] + q[1] * forward[1] + q[2] * forward[2];
    distance = std::max(
        {distance, std::abs(x) / tan_x - depth[corner], std::abs(y) / tan_y - depth[corner]});
  }
  distance = std::max(k_free_margin * distance, 1e-2);
  for (double z : depth) {
    nearest = std::min(nearest, distance + z);
    farthest = std::max(farthest, distance + z);
  }
  v.near_clip = std::max(1e-3, std::min(nearest / 2, m->vis.map.znear * m->stat.extent));
  v.far_clip = std::max(m->vis.map.zfar * m->stat.extent, 2 * farthest);
  for (int i = 0; i < 3; ++i) {
    v.forward[i] = forward[i];
    v.up[i] = up[i];
    v.position[i] = center[i] - distance * forward[i];
  }
  return v;
}

CameraView Snapshotter::view(const SnapshotOptions& o, std::string& camera) const {
  check_size("width", o.width);
  check_size("height", o.height);
  if (o.width * o.height > SnapshotOptions::k_max_pixels)
    throw ServiceError(std::string(k_who) + ": width x height = " + std::to_string(o.width) +
                           " x " + std::to_string(o.height) + " is more than " +
                           std::to_string(SnapshotOptions::k_max_pixels) + " pixels (4096 x 4096)",
                       Failure::bad_arguments, {{"parameter", "width"}});
  const mjModel* m = sim_.m();
  const int id = o.camera.empty() ? -1 : mj_name2id(m, mjOBJ_CAMERA, o.camera.c_str());
  if (id < 0 && !o.camera.empty() && o.camera != "free")
    throw ServiceError(std::string(k_who) + ": camera '" + o.camera +
                           "' is not an MJCF camera of the scene (its cameras: " + camera_names(m) +
                           "; \"\" or \"free\": a view of the whole scene)",
                       Failure::bad_arguments, {{"parameter", "camera"}});
  const int width = static_cast<int>(o.width), height = static_cast<int>(o.height);
  if (id < 0) {
    camera = "free";
    return free_view(m, sim_.d(), width, height);
  }
  camera = o.camera;
  CameraView v;
  v.width = width;
  v.height = height;
  v.fovy = m->cam_fovy[id];
  const double extent = m->stat.extent > 0 ? m->stat.extent : 1.0;
  v.near_clip = m->vis.map.znear * extent;
  v.far_clip = m->vis.map.zfar * extent;
  mjcf_camera_pose(v, sim_.d(), id);
  return v;
}

Renderer& Snapshotter::renderer() {
  if (!renderer_) renderer_ = Renderer::shared();
  if (const std::string why = renderer_->unavailable(); !why.empty())
    throw ServiceError(std::string(k_who) + ": cannot render: " + why);
  return *renderer_;
}

std::unique_ptr<SceneCopy> Snapshotter::scene(const CameraView& view) {
  auto scene = std::make_unique<SceneCopy>(model_copy_.get(*renderer_, sim_));
  scene->update(sim_.m(), sim_.d(), view, sim_.state_time());
  return scene;
}

std::size_t Snapshotter::InFlight::still_wanted() {
  std::lock_guard lock(mutex);
  return static_cast<std::size_t>(std::count_if(wanted.begin(), wanted.end(),
                                                [](const auto& entry) { return entry.second(); }));
}

void Snapshotter::start(const SnapshotOptions& options, Done done, std::function<bool()> wanted) {
  std::string camera;
  const CameraView v = view(options, camera);
  Renderer& r = renderer();
  if (in_flight_->still_wanted() >= k_max_in_flight)
    throw ServiceError(
        std::string(k_who) + ": " + std::to_string(k_max_in_flight) +
            " snapshots are being rendered already (the limit): ask again when one is done",
        Failure::service_error, {{"limit", k_max_in_flight}});
  auto copy = scene(v);
  std::uint64_t ticket = 0;
  {
    std::lock_guard lock(in_flight_->mutex);
    ticket = in_flight_->next_ticket++;
    in_flight_->wanted.emplace(ticket, wanted ? wanted : [] { return true; });
  }
  r.render(
      std::move(copy), true, false,
      [done = std::move(done), camera, in_flight = in_flight_, ticket](RenderResult result) {
        {
          std::lock_guard lock(in_flight->mutex);
          in_flight->wanted.erase(ticket);
        }
        std::string error = result.error;
        json record;
        if (error.empty()) {
          try {
            record = rgb_image_record(result);
          } catch (const std::exception& e) {
            error = std::string("could not encode the image: ") + e.what();
          }
        }
        if (!error.empty()) {
          done(Status::failed, json(std::string(k_who) + ": " + error));
          return;
        }
        record["camera"] = camera;
        record["view"] = view_json(result.view);
        done(Status::success, std::move(record));
      },
      std::move(wanted));
}

json Snapshotter::take(const SnapshotOptions& options, std::chrono::milliseconds timeout) {
  // shared with the callback, which may run after a timeout
  auto promise = std::make_shared<std::promise<std::pair<Status, json>>>();
  auto future = promise->get_future();
  start(options,
        [promise](Status status, json value) { promise->set_value({status, std::move(value)}); });
  if (future.wait_for(timeout) != std::future_status::ready)
    throw ServiceError(std::string(k_who) + ": no image within " +
                       std::to_string(timeout.count() / 1000) + " s");
  auto [status, value] = future.get();
  if (status != Status::success)
    throw ServiceError(value.is_string() ? value.get<std::string>() : value.dump());
  return value;
}

void add_snapshot_services(SupervisionServices& simulation, Simulation& sim) {
  auto snapshots = std::make_shared<Snapshotter>(sim);
  simulation
      .offer_async_service(
          "get_snapshot",
          [snapshots](Completion done, std::string camera, std::int64_t width,
                      std::int64_t height) {
            snapshots->start(
                {std::move(camera), width, height},
                [done](Status status, json value) { done(status, std::move(value)); },
                [done] { return !done.done(); });  // its client may leave before its turn
          },
          {{"camera", ""},
           {"width", SnapshotOptions::k_default_width},
           {"height", SnapshotOptions::k_default_height}})
      .concurrent()
      .doc(
          "A picture of the scene (rendered off the lock): from MJCF camera `camera`, or \"\" for "
          "a free view of the "
          "whole scene; {image (base64 PNG), width, height, format, encoding, timestamp, camera, "
          "view}");
}

}  // namespace simgate::sim
