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
// Each reply carries the images' pixels raw beside their records (Outcome::attachments);
// for a caller that takes them raw (CallContext::takes_raw_attachments: a DDS client reading
// its replies' images) the records have no PNG ("format": "raw") and none is encoded, the
// attachments making it (to_json) should the transport need it after all. A get_local_data
// that wants the PNG of a last image made raw gets an image rendered now, as its first one:
// no PNG is ever encoded under the simulation lock.
//
// Stream (docs/components/cameras.md 'Streams'): a pushed output stream of kind "image"
// (video) or "depth_image" (depth), at `frequency` images per simulated second. Only while
// it has subscribers the camera renders, on the path capture uses (the scene copied under
// the lock, rendered on the render thread), and pushes each image from default_action()
// when it comes back: raw pixels (rgb8, or 32FC1 metres) described for typed transports
// (DDS Image), the record get_local_data returns (PNG, base64) made only when a JSON
// transport asks. When the render thread is behind (k_max_stream_in_flight renders
// waiting), an image is skipped, never waited for. Stream images do not change
// get_local_data's last image.
//
// No GL: when the renderer cannot make a context, capture, get_image and get_local_data
// answer FAILED with its reason; the component is created and everything else runs.
//
// Threads: services, default_action(), interrupt() on the simulation thread under the
// lock; images arrive from the render thread into a mailbox that default_action() reads.
#ifndef SIMGATE_SIM_CAMERAS_H_
#define SIMGATE_SIM_CAMERAS_H_

#include <deque>
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
  // Stream renders waiting on the render thread beyond which the next image is skipped.
  static constexpr int k_max_stream_in_flight = 2;

  Camera(ComponentContext& context, Type type);
  ~Camera() override;

  void capture(long long n);
  void get_image(Completion done);
  void get_local_data(Completion done);

  void default_action() override;
  void interrupt() override;
  void on_model_changed(const ModelRemap& remap) override;
  bool uses_frequency() const override { return true; }

  // Where the camera is now and what it sees (from the last computed state).
  CameraView view() const;
  Type type() const { return type_; }
  // Stream images skipped because the render thread was behind.
  std::uint64_t stream_skipped() const { return stream_skipped_; }

 private:
  struct Mailbox;  // shared with the render thread's callbacks

  // The renderer, started on first use; throws ServiceError when it cannot render.
  Renderer& renderer();
  // A scene of the current state, ready for the render thread.
  std::unique_ptr<SceneCopy> scene_now();
  // Renders the current state; the image record (or error) goes to the mailbox under
  // `capture_id` (0: not for a capture) and to `done` when it is given. `png`: the record
  // holds the PNG; else it is raw (its caller takes the pixels raw) and none is encoded.
  void render_now(std::uint64_t capture_id, Completion done, bool png);
  // Renders the current state for the stream: the image goes to the mailbox's stream_images.
  void render_for_stream();
  // default_action's stream part: pushes the images come back (`error`: the last render's
  // failure), renders the next one when the stream is wanted and its time has come.
  void stream_step(const std::string& error, int in_flight);
  // Ends the running capture (its images still coming are dropped).
  void end_capture();
  json pose() const;
  // Its optical frame (pose()'s), on the body the MJCF camera or the frame is fixed to.
  std::optional<SensingFrame> sensing_frame() const override;

  Type type_;
  int camera_ = -1;                     // MJCF camera id, or -1: frame_
  std::string camera_name_;             // its name
  std::optional<SensorFrame> frame_;    // the frame it sees from when camera_ < 0
  int width_, height_;                  // pixels
  double fovy_;                         // vertical field of view, degrees
  double near_, far_;                   // clipping planes, m
  double frequency_;                    // images per simulated second while capturing
  std::shared_ptr<Renderer> renderer_;  // null until the first image
  RenderModelCopy model_copy_;          // the renderer's copy of the current model
  std::shared_ptr<Mailbox> mailbox_;    // images coming back
  // the running capture
  std::uint64_t capture_id_ = 0;  // bumped by each capture (and each end)
  long long to_render_ = 0;       // images still to ask for
  long long expected_ = 0;        // images it returns
  bool capture_png_ = true;       // its records hold PNGs (its caller does not take them raw)
  double next_frame_time_ = 0;    // simulated time of the next image
  json images_ = json::array();   // its images so far
  // their pixels raw (attachments)
  std::vector<std::shared_ptr<const StreamPayload>> image_pixels_;
  // the stream
  double next_stream_time_ = 0;       // simulated time of its next image
  double stream_clock_ = 0;           // simulated time at its last look (a reset goes back)
  bool stream_idle_ = true;           // nobody wanted it at the last look
  std::uint64_t stream_skipped_ = 0;  // images skipped (render thread behind)
  bool stream_error_logged_ = false;
  std::deque<std::shared_ptr<const StreamPayload>> stream_images_;  // default_action's, reused
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_CAMERAS_H_
