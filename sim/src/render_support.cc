// What the cameras and the snapshot service share (render_support.h).
#include "simgate/sim/render_support.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "simgate/sim/image_codec.h"
#include "simgate/sim/simulation.h"

namespace simgate::sim {

std::string camera_names(const mjModel* m) {
  std::string out;
  for (int i = 0; i < m->ncam; ++i) {
    const char* name = mj_id2name(m, mjOBJ_CAMERA, i);
    out += (out.empty() ? "" : ", ") + std::string(name ? name : "(unnamed)");
  }
  return out.empty() ? "none" : out;
}

void mjcf_camera_pose(CameraView& v, const mjData* d, int camera) {
  const mjtNum* p = d->cam_xpos + 3 * camera;
  const mjtNum* r = d->cam_xmat + 9 * camera;  // row-major
  for (int i = 0; i < 3; ++i) {
    v.position[i] = p[i];
    v.forward[i] = -r[3 * i + 2];  // looks along -z
    v.up[i] = r[3 * i + 1];        // y up
  }
}

void frame_pose(CameraView& v, const mjtNum* p, const mjtNum* r) {
  for (int i = 0; i < 3; ++i) {
    v.position[i] = p[i];
    v.forward[i] = r[3 * i];  // looks along +x
    v.up[i] = r[3 * i + 2];   // z up
  }
}

namespace {

json record_base(int width, int height, json intrinsic, double timestamp, bool png) {
  return {{"width", width},
          {"height", height},
          {"format", png ? "png" : "raw"},
          {"intrinsic_matrix", std::move(intrinsic)},
          {"timestamp", timestamp}};
}

}  // namespace

json rgb_image_record(int width, int height, std::span<const std::uint8_t> rgb, json intrinsic,
                      double timestamp, bool png) {
  json record = record_base(width, height, std::move(intrinsic), timestamp, png);
  record["encoding"] = "rgb8";
  if (png) record["image"] = base64_encode(encode_png_rgb8(rgb, width, height));
  return record;
}

json depth_image_record(int width, int height, std::span<const float> depth, json intrinsic,
                        double timestamp, bool png) {
  // depth in millimetres, 0 where nothing is hit; the nearest and farthest hit in metres
  // (given raw too: the record says them either way)
  json record = record_base(width, height, std::move(intrinsic), timestamp, png);
  std::vector<std::uint16_t> mm(png ? depth.size() : 0);
  double lowest = std::numeric_limits<double>::infinity(), highest = 0;
  for (std::size_t i = 0; i < depth.size(); ++i) {
    const double z = depth[i];
    if (z <= 0) continue;
    lowest = std::min(lowest, z);
    highest = std::max(highest, z);
    if (png) mm[i] = static_cast<std::uint16_t>(std::clamp(std::lround(z * 1000), 1L, 65535L));
  }
  record["encoding"] = "mono16";
  record["depth_unit"] = "mm";
  record["min_depth"] = highest > 0 ? json(lowest) : json(nullptr);
  record["max_depth"] = highest > 0 ? json(highest) : json(nullptr);
  if (png) record["image"] = base64_encode(encode_png_gray16(mm, width, height));
  return record;
}

json rgb_image_record(const RenderResult& r, bool png) {
  return rgb_image_record(r.width, r.height, r.rgb, intrinsic_matrix(r.view), r.timestamp, png);
}

json depth_image_record(const RenderResult& r, bool png) {
  return depth_image_record(r.width, r.height, r.depth, intrinsic_matrix(r.view), r.timestamp, png);
}

const std::shared_ptr<const mjModel>& RenderModelCopy::get(Renderer& renderer,
                                                           const Simulation& sim) {
  if (!copy_ || generation_ != sim.model_generation()) {
    copy_ = renderer.model_copy(sim.m());
    generation_ = sim.model_generation();
  }
  return copy_;
}

}  // namespace simgate::sim
