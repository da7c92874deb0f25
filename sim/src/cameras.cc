// video_camera and depth_camera (cameras.h): options, the view, image records, capture.
#include "simgate/sim/cameras.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <cmath>
#include <deque>
#include <limits>
#include <mutex>

#include <Eigen/Geometry>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/streams.h"
#include "simgate/sim/render_support.h"

namespace simgate::sim {

namespace {

constexpr long long k_max_size = 8192;                // pixels, either side
constexpr double k_min_fovy = 0.1, k_max_fovy = 179;  // degrees
constexpr double k_default_frequency = 20;            // images per simulated second
// MORSE's cam_focal is a Blender lens: millimetres, on a 32 mm wide sensor (its larger side)
constexpr double k_blender_sensor = 32;  // mm

// The JSON record of one image (render_support.h), with its PNG or raw. Render thread.
json image_record(const RenderResult& r, Camera::Type type, bool png) {
  return type == Camera::Type::video ? rgb_image_record(r, png) : depth_image_record(r, png);
}

// `record` as a caller that takes the pixels raw gets it: no image, "format": "raw" (the
// PNG's base64 not copied).
json raw_record(const json& record) {
  if (!record.contains("image")) return record;
  json raw = json::object();
  for (auto it = record.begin(); it != record.end(); ++it)
    if (it.key() != "image") raw[it.key()] = it.value();
  raw["format"] = "raw";
  return raw;
}

// A stream sample of one image: its pixels raw (video: "rgb8", 3 bytes a pixel; depth:
// "32FC1", a float in metres a pixel, 0 where nothing is hit; host byte order, rows top
// first), described for typed transports; its record (the same as get_local_data's, PNG in
// base64) made only when a JSON transport asks. Also a reply's attachment (Outcome::
// attachments): the same pixels beside the record, to_json making the PNG record when a
// transport has to send a raw record's image as a PNG after all. Render thread; takes r's
// pixels.
std::shared_ptr<const StreamPayload> image_payload(RenderResult& r, Camera::Type type,
                                                   const std::string& component) {
  auto payload = std::make_shared<StreamPayload>();
  payload->content = "image";
  const bool video = type == Camera::Type::video;
  const int pixel = video ? 3 : static_cast<int>(sizeof(float));
  payload->description = {{"component", component},
                          {"width", r.width},
                          {"height", r.height},
                          {"encoding", video ? "rgb8" : "32FC1"},
                          {"step", r.width * pixel},
                          {"is_bigendian", std::endian::native == std::endian::big},
                          {"intrinsic_matrix", intrinsic_matrix(r.view)},
                          {"timestamp", r.timestamp}};
  if (video) {
    payload->bytes = std::move(r.rgb);
  } else {
    payload->bytes.resize(r.depth.size() * sizeof(float));
    std::memcpy(payload->bytes.data(), r.depth.data(), payload->bytes.size());
  }
  payload->to_json = [type](const StreamPayload& p) {
    const json& d = p.description;
    const int width = d.at("width"), height = d.at("height");
    if (type == Camera::Type::video)
      return rgb_image_record(width, height, p.bytes, d.at("intrinsic_matrix"), d.at("timestamp"));
    std::vector<float> depth(p.bytes.size() / sizeof(float));
    std::memcpy(depth.data(), p.bytes.data(), depth.size() * sizeof(float));
    return depth_image_record(width, height, depth, d.at("intrinsic_matrix"), d.at("timestamp"));
  };
  return payload;
}

}  // namespace

// Images coming back from the render thread, and the spare scene for the next one.
struct Camera::Mailbox {
  struct Delivery {
    std::uint64_t capture_id;                     // the capture it is for (0: none)
    json record;                                  // the image record, or null on error
    std::shared_ptr<const StreamPayload> pixels;  // its pixels raw (the reply's attachment)
    std::string error;                            // why it failed
  };
  std::mutex mutex;
  std::deque<Delivery> deliveries;  // for captures, read by default_action()
  std::deque<std::shared_ptr<const StreamPayload>> stream_images;  // for the stream, ditto
  std::string stream_error;  // why the last stream render failed ("" when it did not)
  int stream_in_flight = 0;  // stream renders asked for and not come back
  json last;                 // the last image record (null: none yet)
  std::shared_ptr<const StreamPayload> last_pixels;  // its pixels raw
  std::string last_error;                            // why the last render failed
  std::unique_ptr<SceneCopy> spare;                  // a scene given back, for reuse
};

Camera::Camera(ComponentContext& c, Type type)
    : SimComponent(c.name(), c.sim()), type_(type), mailbox_(std::make_shared<Mailbox>()) {
  const mjModel* m = c.sim().m();
  ConfigObject& o = c.options();
  // where it sees from: an MJCF camera, or a frame of the robot
  const std::string camera = o.get_string("camera", "");
  if (!camera.empty()) {
    if (o.has("site"))
      o.fail("site", "no `site` with `camera` (the MJCF camera is where it sees from)");
    camera_ = mj_name2id(m, mjOBJ_CAMERA, camera.c_str());
    camera_name_ = camera;
    if (camera_ < 0)
      o.fail("camera", "the name of an MJCF <camera> (the scene has: " + camera_names(m) + ")");
  } else {
    frame_ = SensorFrame::from(c);
    // the body's own frame is usually inside the body's geometry: the images show its inside
    if (!o.has("site"))
      log::warning("camera '", c.name(),
                   "': no `site` and no `camera`: it looks out from the origin of body '",
                   c.sim().model().body_name(frame_->body()),
                   "', likely from inside the body's own geometry (give it a `site` on the body's "
                   "surface, or an "
                   "MJCF <camera>; docs/components/cameras.md)");
  }
  width_ = static_cast<int>(o.get_int("cam_width", 256, 1, k_max_size));
  height_ = static_cast<int>(o.get_int("cam_height", 256, 1, k_max_size));
  // field of view: cam_fovy (degrees), or MORSE's cam_focal; default the MJCF camera's
  if (o.has("cam_fovy") && o.has("cam_focal"))
    o.fail("cam_focal", "either cam_fovy or cam_focal, not both");
  fovy_ =
      o.get_number("cam_fovy", camera_ >= 0 ? m->cam_fovy[camera_] : 45.0, k_min_fovy, k_max_fovy);
  if (o.has("cam_focal")) {
    const double focal = o.get_number("cam_focal", 25, 0.1, 1e4);
    const double half_large =
        k_blender_sensor / 2 / focal;  // tan of the half angle of the larger side
    const double half_y = width_ >= height_ ? half_large * height_ / width_ : half_large;
    fovy_ = std::atan(half_y) * 360 / M_PI;
  }
  // clipping planes: MuJoCo's own for the scene by default
  near_ = o.get_number("cam_near", m->vis.map.znear * m->stat.extent, 1e-6, 1e6);
  far_ = o.get_number("cam_far", m->vis.map.zfar * m->stat.extent, 1e-6, 1e7);
  if (far_ <= near_)
    o.fail("cam_far", "a distance beyond cam_near (" + std::to_string(near_) + " m)");
  frequency_ = c.spec().frequency.value_or(k_default_frequency);
  if (!(frequency_ > 0)) o.fail("frequency", "images per simulated second, > 0");
  // the image stream: rendered only while someone subscribes, pushed when it comes back
  declare_pushed_stream(type_ == Type::video ? "image" : "depth_image", frequency_);

  const char* kind = type_ == Type::video ? "RGB" : "depth (mm, 16-bit PNG)";
  add_async_service("capture", &Camera::capture, {"n"})
      .interruptible()
      .doc(std::string("Completes after the next n ") + kind +
           " images (one per 1/frequency of simulated time) with the list of their records");
  add_async_service("get_image", &Camera::get_image)
      .concurrent()
      .doc(std::string("An ") + kind +
           " image of the current state: its record (image: base64 PNG)");
  add_async_service("get_local_data", &Camera::get_local_data)
      .concurrent()
      .doc(
          "The last image record: image (base64 PNG), width, height, intrinsic_matrix, timestamp; "
          "the first one "
          "rendered now, physics stepping meanwhile");
  add_property("cam_width", [this] { return json(width_); });
  add_property("cam_height", [this] { return json(height_); });
  add_property("cam_fovy", [this] { return json(fovy_); });
  add_property("cam_near", [this] { return json(near_); });
  add_property("cam_far", [this] { return json(far_); });
  add_property("frequency", [this] { return json(frequency_); });
  add_property("focal_length", [this] { return json(intrinsic_matrix(view())[1][1]); });
  add_property("principal_point", [this] {
    auto k = intrinsic_matrix(view());
    return json{k[0][2], k[1][2]};
  });
  add_property("intrinsic_matrix", [this] { return json(intrinsic_matrix(view())); });
  add_property("pose", [this] { return pose(); });
}

Camera::~Camera() = default;

CameraView Camera::view() const {
  const mjData* d = data();
  CameraView v;
  v.width = width_;
  v.height = height_;
  v.fovy = fovy_;
  v.near_clip = near_;
  v.far_clip = far_;
  if (camera_ >= 0) {
    mjcf_camera_pose(v, d, camera_);
  } else {
    frame_pose(v, frame_->position(d), frame_->rotation(d));
  }
  return v;
}

std::optional<SimComponent::SensingFrame> Camera::sensing_frame() const {
  // the optical frame (x right, y down, z forward: the intrinsic matrix's) in the world
  const CameraView v = view();
  const Eigen::Vector3d forward(v.forward), up(v.up);
  Eigen::Matrix3d r;
  r.col(0) = forward.cross(up);
  r.col(1) = -up;
  r.col(2) = forward;
  return SensingFrame{camera_ >= 0 ? model()->cam_bodyid[camera_] : frame_->body(),
                      Eigen::Vector3d(v.position[0], v.position[1], v.position[2]),
                      Eigen::Quaterniond(r)};
}

json Camera::pose() const {
  const SensingFrame f = *sensing_frame();
  const Eigen::Quaterniond& q = f.orientation;
  return {{"position", {f.position.x(), f.position.y(), f.position.z()}},
          {"orientation", {q.w(), q.x(), q.y(), q.z()}},
          {"frame", "optical: x right, y down, z forward (world frame)"}};
}

Renderer& Camera::renderer() {
  if (!renderer_) renderer_ = Renderer::shared();
  if (const std::string why = renderer_->unavailable(); !why.empty())
    throw ServiceError(name() + ": cannot render: " + why);
  return *renderer_;
}

std::unique_ptr<SceneCopy> Camera::scene_now() {
  Renderer& r = renderer();
  const mjModel* m = model();
  const std::shared_ptr<const mjModel>& model_copy = model_copy_.get(r, sim());
  std::unique_ptr<SceneCopy> scene;
  {
    std::lock_guard lock(mailbox_->mutex);
    scene = std::move(mailbox_->spare);
  }
  if (!scene || scene->model() != model_copy) scene = std::make_unique<SceneCopy>(model_copy);
  scene->update(m, data(), view(), sim().state_time());
  return scene;
}

void Camera::render_for_stream() {
  std::unique_ptr<SceneCopy> scene = scene_now();
  const bool depth = type_ == Type::depth;
  {
    std::lock_guard lock(mailbox_->mutex);
    ++mailbox_->stream_in_flight;
  }
  renderer_->render(std::move(scene), !depth, depth,
                    [mailbox = mailbox_, type = type_, who = name()](RenderResult result) {
                      std::shared_ptr<const StreamPayload> payload;
                      std::string error = result.error.empty() ? "" : who + ": " + result.error;
                      if (error.empty()) payload = image_payload(result, type, who);
                      std::lock_guard lock(mailbox->mutex);
                      mailbox->spare = std::move(result.scene);
                      --mailbox->stream_in_flight;
                      mailbox->stream_error = error;
                      if (payload) mailbox->stream_images.push_back(std::move(payload));
                    });
}

void Camera::render_now(std::uint64_t capture_id, Completion done, bool png) {
  std::unique_ptr<SceneCopy> scene = scene_now();
  const bool depth = type_ == Type::depth;
  renderer_->render(
      std::move(scene), !depth, depth,
      [mailbox = mailbox_, type = type_, capture_id, done, png, who = name()](RenderResult result) {
        json record;
        std::shared_ptr<const StreamPayload> pixels;
        std::string error = result.error.empty() ? "" : who + ": " + result.error;
        if (error.empty()) {
          try {
            record = image_record(result, type, png);
            // (after the record: takes the pixels)
            pixels = image_payload(result, type, who);
          } catch (const std::exception& e) {
            error = who + ": could not encode the image: " + e.what();
          }
        }
        {
          std::lock_guard lock(mailbox->mutex);
          mailbox->spare = std::move(result.scene);
          if (error.empty()) {
            mailbox->last = record;
            mailbox->last_pixels = pixels;
          }
          mailbox->last_error = error;
          if (capture_id != 0) mailbox->deliveries.push_back({capture_id, record, pixels, error});
        }
        if (!done) return;
        if (!error.empty()) {
          done(Status::failed, json(error));
          return;
        }
        // the record, and its pixels raw for the transports that send them typed
        Outcome outcome = Outcome::success(std::move(record));
        outcome.attachments.push_back(std::move(pixels));
        done.finish(std::move(outcome));
      });
}

void Camera::capture(long long n) {
  if (n < 1 || n > k_max_capture)
    throw ServiceError(name() + " capture: n is the number of images, from 1 to " +
                           std::to_string(k_max_capture) + ", found " + std::to_string(n),
                       Failure::bad_arguments, {{"parameter", "n"}});
  renderer();  // FAILED now when nothing can be rendered
  end_capture();
  to_render_ = expected_ = n;
  capture_png_ = !caller_takes_raw_attachments();
  // the first image is of the state the next step starts from
  next_frame_time_ = sim().sim_time();
}

void Camera::get_image(Completion done) {
  try {
    render_now(0, done, !caller_takes_raw_attachments());
  } catch (const ServiceError& e) {
    done(Status::failed, e.what());
  }
}

void Camera::get_local_data(Completion done) {
  const bool raw = caller_takes_raw_attachments();
  Outcome outcome;
  {
    std::lock_guard lock(mailbox_->mutex);
    const json& last = mailbox_->last;
    // the last record as this caller takes it; a raw one (made for a caller that took it
    // raw) has no PNG for one that does not: as if there were none
    if (raw)
      outcome.value = raw_record(last);
    else if (last.contains("image"))
      outcome.value = last;
    else
      outcome.value = json(nullptr);
    outcome.attachments.push_back(mailbox_->last_pixels);  // its pixels raw, for typed transports
  }
  if (!outcome.value->is_null()) {
    done.finish(std::move(outcome));
    return;
  }
  // none yet (or none with its PNG): one rendered now, answered from the render thread as
  // get_image is; physics keeps stepping meanwhile (nothing waits under the lock, no PNG is
  // encoded under it)
  get_image(std::move(done));
}

void Camera::default_action() {
  // images of the running capture and of the stream that came back
  std::deque<Mailbox::Delivery> arrived;
  std::string stream_error;
  int stream_in_flight = 0;
  {
    std::lock_guard lock(mailbox_->mutex);
    arrived.swap(mailbox_->deliveries);
    stream_images_.swap(mailbox_->stream_images);
    stream_error = mailbox_->stream_error;
    stream_in_flight = mailbox_->stream_in_flight;
  }
  stream_step(stream_error, stream_in_flight);
  for (Mailbox::Delivery& delivery : arrived) {
    if (delivery.capture_id != capture_id_ || !has_running_request())
      continue;  // of an ended capture
    if (!delivery.error.empty()) {
      end_capture();
      completed(Status::failed, delivery.error);
      return;
    }
    images_.push_back(std::move(delivery.record));
    image_pixels_.push_back(std::move(delivery.pixels));
    if (static_cast<long long>(images_.size()) == expected_) {
      // the records, and their pixels raw for the transports that send them typed
      Outcome outcome = Outcome::success(std::move(images_));
      outcome.attachments = std::move(image_pixels_);
      Completion done = async_slot()->running_completion;
      end_capture();
      done.finish(std::move(outcome));
      return;
    }
  }
  // the next image of the running capture, when its time has come
  if (to_render_ <= 0 || !has_running_request()) return;
  const double now = sim().sim_time();
  if (now + 0.5 * sim().timestep() < next_frame_time_) return;
  try {
    render_now(capture_id_, Completion(), capture_png_);
  } catch (const ServiceError& e) {
    end_capture();
    completed(Status::failed, e.what());
    return;
  }
  --to_render_;
  next_frame_time_ += 1.0 / frequency_;
}

void Camera::stream_step(const std::string& error, int in_flight) {
  // the images that came back, in the order rendered (nobody may want them any more: then
  // push_sample takes none)
  for (auto& image : stream_images_) {
    const double time = image->description.at("timestamp").get<double>();
    push_sample(time, std::move(image));
  }
  stream_images_.clear();
  if (!error.empty() && !stream_error_logged_) {
    stream_error_logged_ = true;
    log::warning(error, " (the image stream gives no image while rendering fails; logged once)");
  }
  // the schedule in the time of the state an image shows (its timestamp): images exactly
  // 1/frequency apart (the first step's state is of the step's start, the next ones' of
  // one timestep before sim_time)
  const double now = sim().state_time();
  if (!stream_wanted()) {
    stream_idle_ = true;
    return;
  }
  // the first image as soon as someone subscribes; after a reset of the clock, from the new time
  if (stream_idle_ || now < stream_clock_) next_stream_time_ = now;
  stream_idle_ = false;
  stream_clock_ = now;
  if (now + 0.5 * sim().timestep() < next_stream_time_) return;
  next_stream_time_ += 1.0 / frequency_;
  if (next_stream_time_ <= now)
    next_stream_time_ = now + 1.0 / frequency_;  // a reset, or a long pause
  // the render thread behind: this image is skipped rather than queued (physics never waits)
  if (in_flight >= k_max_stream_in_flight) {
    ++stream_skipped_;
    note_skipped_sample();  // counted in the stream's statistics (skipped, dropped)
    return;
  }
  try {
    render_for_stream();
  } catch (const ServiceError& e) {
    // no GL: the stream gives nothing; logged once
    if (!stream_error_logged_) {
      stream_error_logged_ = true;
      log::warning(e.what(), " (the image stream gives no image; logged once)");
    }
  }
}

void Camera::end_capture() {
  ++capture_id_;
  to_render_ = expected_ = 0;
  capture_png_ = true;
  images_ = json::array();
  image_pixels_.clear();
}

void Camera::interrupt() {
  end_capture();
  Component::interrupt();
}

void Camera::on_model_changed(const ModelRemap& remap) {
  // MuJoCo's remap has no cameras: the camera by its name
  if (camera_ >= 0) {
    camera_ = mj_name2id(model(), mjOBJ_CAMERA, camera_name_.c_str());
    if (camera_ < 0)
      throw std::logic_error(name() + ": MJCF camera '" + camera_name_ + "' is gone");
  }
  if (frame_) frame_->remap(remap);
}

namespace {
const std::vector<OptionSpec> camera_options = {
    {"camera", {{"type", "string"}}, "an MJCF <camera> to see from (looks along its -z, +y up)"},
    {"site",
     {{"type", "string"}},
     "without camera: a MuJoCo site on the robot to see from (looks along its +x, +z up; default: "
     "the body's frame)"},
    {"cam_width",
     {{"type", "integer"}, {"minimum", 1}, {"maximum", 8192}, {"default", 256}},
     "pixels"},
    {"cam_height",
     {{"type", "integer"}, {"minimum", 1}, {"maximum", 8192}, {"default", 256}},
     "pixels"},
    {"cam_fovy",
     {{"type", "number"}, {"minimum", 0.1}, {"maximum", 179}},
     "vertical field of view, degrees (default the MJCF camera's, else 45)"},
    {"cam_focal",
     {{"type", "number"}, {"minimum", 0.1}, {"maximum", 1e4}},
     "MORSE's focal length: mm on a 32 mm sensor (its larger side); instead of cam_fovy"},
    {"cam_near",
     {{"type", "number"}, {"minimum", 1e-6}, {"maximum", 1e6}},
     "near clipping plane, m (default MuJoCo's: znear x extent)"},
    {"cam_far",
     {{"type", "number"}, {"minimum", 1e-6}, {"maximum", 1e7}},
     "far clipping plane, m (default MuJoCo's: zfar x extent)"}};
}  // namespace

SIMGATE_BUILTIN_TYPE(video_camera,
                     builtin_type("video_camera", Kind::component,
                                  "RGB camera rendered headless (MJCF camera or robot frame): "
                                  "capture n, get_image, get_local_data (base64 PNG)",
                                  "docs/components/cameras.md", camera_options,
                                  [](ComponentContext& c) -> std::unique_ptr<SimComponent> {
                                    return std::make_unique<Camera>(c, Camera::Type::video);
                                  }));
SIMGATE_BUILTIN_TYPE(
    depth_camera,
    builtin_type(
        "depth_camera", Kind::component,
        "depth camera (mm, 16-bit PNG) rendered headless: capture n, get_image, get_local_data",
        "docs/components/cameras.md", camera_options,
        [](ComponentContext& c) -> std::unique_ptr<SimComponent> {
          return std::make_unique<Camera>(c, Camera::Type::depth);
        }));

}  // namespace simgate::sim
