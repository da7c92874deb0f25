// simgate/sim/cameras.h — MORSE's video_camera and a depth_camera, rendered headless.
//
// A camera sees from an MJCF <camera> (option `camera`: its name; it looks along the
// camera's -z with +y up, MuJoCo's convention) or from a sensor frame of its robot (option
// `site`, else its body; it looks along the frame's +x with +z up, as the other sensors
// measure). Its images are rendered by the process's Renderer (renderer.h): the scene is
// copied under the simulation lock, rendered and encoded on the render thread.
//
//  - video_camera: 8-bit RGB images.
//  - depth_camera: the distance along the optical axis of what each pixel sees, from
//    MuJoCo's depth buffer, as a 16-bit grayscale PNG in millimetres (0: nothing within
//    cam_far; 65535: 65.535 m or farther).
//
// Services: async `capture n` (MORSE's): completes after the next n images, one per
// 1/frequency of simulated time, with the list of their image records; `get_image`:
// an image of the current state (a concurrent async service: physics steps on while it
// renders); `get_local_data`: the last image record (or, when none was rendered yet, one
// rendered now). docs/components/cameras.md has the options, the record and wire examples.
//
// No GL: when the renderer cannot make a context, capture, get_image and get_local_data
// answer FAILED with its reason; the component is created and everything else runs.
//
// Threads: services, default_action(), interrupt() on the simulation thread under the
// lock; images arrive from the render thread into a mailbox that default_action() reads.
#ifndef SIMGATE_SIM_CAMERAS_H_
#define SIMGATE_SIM_CAMERAS_H_

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "simgate/sim/native_sensors.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/render_support.h"
#include "simgate/sim/renderer.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

class Camera : public SimComponent {
 public:
  enum class Type { video, depth };
  // The most images one capture returns (each is carried in its one reply).
  static constexpr long long k_max_capture = 100;

  Camera(ComponentContext& context, Type type);
  ~Camera() override;

  void capture(long long n);
  void get_image(Completion done);
  json get_local_data();

  void default_action() override;
  void interrupt() override;
  void on_model_changed(const ModelRemap& remap) override;
  bool uses_frequency() const override { return true; }

  // Where the camera is now and what it sees (from the last computed state).
  CameraView view() const;
  Type type() const { return type_; }

 private:
  struct Mailbox;  // shared with the render thread's callbacks

  // The renderer, started on first use; throws ServiceError when it cannot render.
  Renderer& renderer();
  // A scene of the current state, ready for the render thread.
  std::unique_ptr<SceneCopy> scene_now();
  // Renders the current state; the image record (or error) goes to the mailbox under
  // `capture_id` (0: not for a capture) and to `done` when it is given.
  void render_now(std::uint64_t capture_id, Completion done);
  // Ends the running capture (its images still coming are dropped).
  void end_capture();
  json pose() const;

  Type type_;
  int camera_ = -1;                   // MJCF camera id, or -1: frame_
  std::string camera_name_;           // its name
  std::optional<SensorFrame> frame_;  // the frame it sees from when camera_ < 0
  int width_, height_;                // pixels
  double fovy_;                       // vertical field of view, degrees
  double near_, far_;                 // clipping planes, m
  double frequency_;                  // images per simulated second while capturing
  std::shared_ptr<Renderer> renderer_;          // null until the first image
  RenderModelCopy model_copy_;                  // the renderer's copy of the current model
  std::shared_ptr<Mailbox> mailbox_;            // images coming back
  // the running capture
  std::uint64_t capture_id_ = 0;      // bumped by each capture (and each end)
  long long to_render_ = 0;           // images still to ask for
  long long expected_ = 0;            // images it returns
  double next_frame_time_ = 0;        // simulated time of the next image
  json images_ = json::array();       // its images so far
};

// Registers video_camera and depth_camera.
void register_cameras(ComponentRegistry& registry);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_CAMERAS_H_
