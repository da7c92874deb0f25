// camera_scene.h — the scene the camera, snapshot and image-stream tests look at: a rig
// 0.5 m above a grey floor holding MJCF camera "front" (looking along +x) and, when asked,
// site "eye" (for a frame camera); a red box whose near face is 1.7 m in front of it,
// centred on the axis.
#ifndef SIMGATE_TESTS_SIM_CAMERA_SCENE_H_
#define SIMGATE_TESTS_SIM_CAMERA_SCENE_H_

#include <array>
#include <chrono>
#include <cstdint>
#include <string>

namespace simgate::testing {

constexpr double k_red_box_face = 1.7;  // m from the rig to the box's near face
// bounds every wait on the render thread
constexpr auto k_render_deadline = std::chrono::seconds(60);

// A pixel of the red box (RGB, 0-255).
inline bool is_red(const std::array<int, 3>& p) {
  return p[0] > 100 && p[0] > 3 * p[1] && p[0] > 3 * p[2];
}
inline bool is_red(const std::uint8_t* p) { return is_red({p[0], p[1], p[2]}); }

inline std::string red_box_scene(const std::string& model, const std::string& timestep,
                                 const std::string& floor_half, bool eye_site) {
  return R"(<mujoco model=")" + model + R"(">
  <option timestep=")" +
         timestep + R"("/>
  <visual><headlight ambient="0.4 0.4 0.4" diffuse="0.6 0.6 0.6"/></visual>
  <worldbody>
    <light pos="0 0 5" dir="0 0 -1"/>
    <geom name="floor" type="plane" size=")" +
         floor_half + " " + floor_half + R"( 0.1" rgba="0.5 0.5 0.5 1"/>
    <body name="rig" pos="0 0 0.5">
      <geom type="sphere" size="0.01" contype="0" conaffinity="0" rgba="0 0 1 0"/>
      <camera name="front" xyaxes="0 -1 0 0 0 1" fovy="60"/>
)" + (eye_site ? "      <site name=\"eye\"/>\n" : "") +
         R"(    </body>
    <body name="target" pos="2 0 0.5">
      <geom name="red_box" type="box" size="0.3 0.3 0.3" rgba="1 0 0 1"/>
    </body>
  </worldbody>
</mujoco>
)";
}

}  // namespace simgate::testing

#endif  // SIMGATE_TESTS_SIM_CAMERA_SCENE_H_
