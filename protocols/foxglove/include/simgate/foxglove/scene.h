// simgate/foxglove/scene.h — the simulation's scene in Foxglove's message schemas, for the 3D
// panel: every body's world pose as foxglove.FrameTransforms (parent frame "world", child
// frame the body's name), every geom as a primitive of foxglove.SceneUpdate (one entity per
// body, in its frame), made from what the `simulation` component gives every client: its
// `body_poses` stream samples and its `get_scene_geometry` answer
// (docs/world/entities.md). The JSON Schemas are this project's writing of Foxglove's
// message definitions (foxglove/foxglove-sdk `schemas/`); tests/foxglove checks the messages
// against @foxglove/schemas' own. Shared by the foxglove transport and recorders.
//
// Threads: pure functions, any thread.
#ifndef SIMGATE_FOXGLOVE_SCENE_H_
#define SIMGATE_FOXGLOVE_SCENE_H_

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/status.h"

namespace simgate::foxglove {

// The frames of a model: each body's frame id (its name; "world" for body 0, "body<id>"
// for an unnamed one), from a get_scene_geometry answer. Every frame id (the bodies', the
// components') begins with the `prefix` given (a world's "w1/": its frames apart from world
// 0's, which have none, in a client that shows both).
struct SceneFrames {
  std::uint64_t generation = 0;    // the answer's generation (changes with the model)
  std::vector<std::string> names;  // by body id
  // The components' frames (the answer's "frames": a sensor's, a camera's optical one), each
  // fixed to a body: named after the component, at `pos` and `quat` (w first) in the body's.
  struct Fixed {
    std::string name;
    std::size_t body = 0;
    double pos[3] = {0, 0, 0};
    double quat[4] = {1, 0, 0, 0};
  };
  std::vector<Fixed> fixed;
  bool known() const { return !names.empty(); }
  static SceneFrames from_geometry(const json& geometry, std::string_view prefix = {});
};

inline constexpr const char* k_frame_transforms = "foxglove.FrameTransforms";
inline constexpr const char* k_scene_update = "foxglove.SceneUpdate";

// The JSON Schemas of the two messages.
json frame_transforms_schema();
json scene_update_schema();

// A body_poses sample ({timestamp, generation, poses: [[x, y, z, qw, qx, qy, qz] per body]})
// as a foxglove.FrameTransforms message (JSON text): world -> every body but the world, then
// each body -> the components' frames fixed to it (`frames.fixed`).
// "" when the sample is not of `frames`' model (another generation) or malformed.
std::string frame_transforms(const json& body_poses, const SceneFrames& frames);
// A get_scene_geometry answer as a foxglove.SceneUpdate message (JSON text): one entity per
// body with geoms (id "body/<name>", frame id the body's, never expiring), each geom a
// primitive at its pose in the body's frame, in its colour: box -> cube, sphere and
// ellipsoid -> sphere, cylinder -> cylinder, capsule -> cylinder and two spheres, plane ->
// a thin cube (an infinite plane as 20 m), mesh -> triangles (when the answer holds its
// vertices), heightfield -> triangles of its grid (sampled down to 256 points a side). Entities of the previous model's bodies are deleted first (`deletions`: all).
std::string scene_update(const json& geometry, const SceneFrames& frames);

}  // namespace simgate::foxglove

#endif  // SIMGATE_FOXGLOVE_SCENE_H_
