// simgate/sim/render_support.h — pieces every user of the renderer (renderer.h) needs: the
// video_camera and depth_camera components (cameras.h) and the `simulation get_snapshot`
// service (snapshot.h) share them.
//
//  - camera_names: the MJCF cameras of a model, for messages that refuse an unknown one.
//  - mjcf_camera_pose / frame_pose: where a view is, from an MJCF <camera> (it looks along
//    the camera's -z with +y up, MuJoCo's convention) or from a frame (along its +x, +z up,
//    as the sensors measure).
//  - rgb_image_record / depth_image_record: the JSON record of one rendered image (MORSE's
//    VideoCamera local_data fields: image as base64 PNG, width, height, intrinsic_matrix;
//    and format, encoding, timestamp). Render thread (they encode). Without `png` the
//    record has no image and says "format": "raw": for a caller that gets the pixels raw
//    beside it (CallContext::takes_raw_attachments), nothing is encoded.
//  - RenderModelCopy: the renderer's copy of the simulation's current model, remade when
//    the model changes (a spawn, a delete). Under the simulation lock.
#ifndef SIMGATE_SIM_RENDER_SUPPORT_H_
#define SIMGATE_SIM_RENDER_SUPPORT_H_

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include <mujoco/mujoco.h>

#include "simgate/core/status.h"
#include "simgate/sim/renderer.h"

namespace simgate::sim {

class Simulation;

// "front, top" (unnamed ones as "(unnamed)"), or "none".
std::string camera_names(const mjModel* m);

// Sets position, forward and up of `view` from MJCF camera `camera` in `d`.
void mjcf_camera_pose(CameraView& view, const mjData* d, int camera);
// Sets them from a frame: position `p`, rotation `r` (row-major 3x3, MuJoCo's xmat).
void frame_pose(CameraView& view, const mjtNum* p, const mjtNum* r);

json rgb_image_record(const RenderResult& r, bool png = true);
json depth_image_record(const RenderResult& r, bool png = true);
// The same from the pieces (an image kept raw and encoded later: a stream's payload).
// `rgb`: 3 bytes a pixel; `depth`: metres, 0 where nothing is hit; rows top first.
json rgb_image_record(int width, int height, std::span<const std::uint8_t> rgb, json intrinsic,
                      double timestamp, bool png = true);
json depth_image_record(int width, int height, std::span<const float> depth, json intrinsic,
                        double timestamp, bool png = true);

class RenderModelCopy {
 public:
  // The copy of `sim`'s current model the render thread may use.
  const std::shared_ptr<const mjModel>& get(Renderer& renderer, const Simulation& sim);

 private:
  std::shared_ptr<const mjModel> copy_;  // of generation_
  std::uint64_t generation_ = 0;         // Simulation::model_generation() it was made at
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_RENDER_SUPPORT_H_
