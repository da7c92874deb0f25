// The headless renderer (renderer.h): EGL context on the render thread, MuJoCo's
// offscreen framebuffer, scenes copied under the simulation lock and rendered off it.
#include "simgate/sim/renderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <stdexcept>

#include "simgate/core/log.h"
#include "simgate/sim/gl_context.h"

namespace simgate::sim {

namespace {

// How long unavailable() waits for the render thread to try EGL (Mesa's llvmpipe starts in
// well under a second; a driver that hangs must not hang a service).
constexpr auto k_start_timeout = std::chrono::seconds(20);

// Equal models give equal contexts: sizes, the arrays' buffer, visual and statistics.
bool same_model(const mjModel* a, const mjModel* b) {
  return std::memcmp(a, b, offsetof(mjModel, opt)) == 0 && a->nbuffer == b->nbuffer &&
         std::memcmp(&a->vis, &b->vis, sizeof a->vis) == 0 &&
         std::memcmp(&a->stat, &b->stat, sizeof a->stat) == 0 &&
         std::memcmp(a->buffer, b->buffer, static_cast<std::size_t>(a->nbuffer)) == 0;
}

void set3(float* out, const double* in) {
  for (int i = 0; i < 3; ++i) out[i] = static_cast<float>(in[i]);
}

}  // namespace

// ---- SceneCopy ----------------------------------------------------------------------

SceneCopy::SceneCopy(std::shared_ptr<const mjModel> model) : model_(std::move(model)) {
  mjv_defaultScene(&scene_);
  mjv_defaultOption(&option_);
  // every geom once, and room for the dynamic ones MuJoCo adds (tendons, skins)
  mjv_makeScene(model_.get(), &scene_, 2 * model_->ngeom + 2 * model_->ntendon + 100);
}

SceneCopy::~SceneCopy() { mjv_freeScene(&scene_); }

void SceneCopy::update(const mjModel* m, mjData* d, const CameraView& view, double timestamp) {
  view_ = view;
  timestamp_ = timestamp;
  // the geoms of the bodies (no decorations: no sites, joints, contacts, perturbation)
  mjvPerturb perturb;
  mjv_defaultPerturb(&perturb);
  scene_.ngeom = 0;
  mjv_addGeoms(m, d, &option_, &perturb, mjCAT_STATIC | mjCAT_DYNAMIC, &scene_);
  // the camera, both eyes (mono), with its own frustum: square pixels, the horizontal
  // extent follows from the viewport's aspect ratio (mjr_render)
  const double half = std::tan(view.fovy * M_PI / 360.0);
  for (mjvGLCamera& cam : scene_.camera) {
    set3(cam.pos, view.position);
    set3(cam.forward, view.forward);
    set3(cam.up, view.up);
    cam.frustum_center = 0;
    cam.frustum_near = static_cast<float>(view.near_clip);
    cam.frustum_far = static_cast<float>(view.far_clip);
    cam.frustum_top = static_cast<float>(view.near_clip * half);
    cam.frustum_bottom = -cam.frustum_top;
  }
  // lights after the camera: the headlight sits at it
  mjv_makeLights(m, d, &scene_);
  if (m->nskin > 0) mjv_updateSkin(m, d, &scene_);
}

// ---- the GL side: render thread only --------------------------------------------------

struct Renderer::Gl {
  std::unique_ptr<GlContext> context;        // current on the render thread
  mjrContext con;                            // MuJoCo's GL resources
  bool con_made = false;                     // con holds resources
  std::shared_ptr<const mjModel> con_model;  // the model con was made from
  int con_width = 0, con_height = 0;         // its offscreen buffer

  // Makes the EGL context current; "" or why not.
  std::string open();
  void close();
};

std::string Renderer::Gl::open() {
  std::string why;
  context = GlContext::make(why);
  return why;
}

void Renderer::Gl::close() {
  if (con_made) mjr_freeContext(&con);
  con_made = false;
  con_model.reset();
  context.reset();
}

// ---- Renderer -------------------------------------------------------------------------

std::shared_ptr<Renderer> Renderer::shared() {
  static std::mutex mutex;
  static std::weak_ptr<Renderer> current;
  std::lock_guard lock(mutex);
  if (auto alive = current.lock()) return alive;
  std::shared_ptr<Renderer> made(new Renderer());
  current = made;
  return made;
}

Renderer::Renderer() : gl_(std::make_unique<Gl>()) { thread_ = std::thread(&Renderer::run, this); }

Renderer::~Renderer() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  // a callback may have let the last holder go: the thread cannot join itself
  if (thread_.get_id() == std::this_thread::get_id())
    thread_.detach();
  else if (thread_.joinable())
    thread_.join();
}

std::string Renderer::unavailable() {
  std::unique_lock lock(mutex_);
  if (!started_cv_.wait_for(lock, k_start_timeout, [this] { return started_; }))
    return "EGL did not make a context within " + std::to_string(k_start_timeout.count()) + " s";
  return unavailable_;
}

std::uint64_t Renderer::renders() const {
  std::lock_guard lock(mutex_);
  return renders_;
}

std::uint64_t Renderer::abandoned() const {
  std::lock_guard lock(mutex_);
  return abandoned_;
}

bool Renderer::idle() const {
  std::lock_guard lock(mutex_);
  return queue_.empty() && !busy_;
}

std::shared_ptr<const mjModel> Renderer::model_copy(const mjModel* m) {
  std::lock_guard lock(copy_mutex_);
  if (last_copy_ && same_model(last_copy_.get(), m)) return last_copy_;
  mjModel* copy = mj_copyModel(nullptr, m);
  if (!copy) throw std::runtime_error("renderer: could not copy the model");
  last_copy_ = std::shared_ptr<const mjModel>(
      copy, [](const mjModel* p) { mj_deleteModel(const_cast<mjModel*>(p)); });
  return last_copy_;
}

void Renderer::render(std::unique_ptr<SceneCopy> scene, bool want_rgb, bool want_depth,
                      Callback done, std::function<bool()> wanted) {
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(
        Job{std::move(scene), want_rgb, want_depth, std::move(done), std::move(wanted)});
  }
  wake_.notify_one();
}

void Renderer::run() {
  std::string why;
  try {
    why = gl_->open();
  } catch (const std::exception& e) {
    why = std::string("EGL failed: ") + e.what();
  }
  if (!why.empty()) log::warning("renderer: ", why, "; cameras will answer FAILED");
  {
    std::lock_guard lock(mutex_);
    unavailable_ = why;
    started_ = true;
  }
  started_cv_.notify_all();

  for (;;) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (stop_) break;
      job = std::move(queue_.front());
      queue_.pop_front();
      busy_ = true;
    }
    RenderResult result;
    result.view = job.scene->view();
    result.timestamp = job.scene->timestamp();
    const bool abandoned = job.wanted && !job.wanted();
    if (!why.empty()) {
      result.error = why;
    } else if (abandoned) {
      // its request ended while it waited (its client left, or cancelled it): no GL work
      // for nobody (issue #35, item 7: a client's 300 large snapshots, then gone)
      result.error = "abandoned: its request ended before its turn";
    } else {
      try {
        render_job(job, result);
      } catch (const std::exception& e) {
        result.error = std::string("render failed: ") + e.what();
      }
    }
    result.scene = std::move(job.scene);
    {
      std::lock_guard lock(mutex_);
      ++(abandoned ? abandoned_ : renders_);
    }
    try {
      job.done(std::move(result));
    } catch (const std::exception& e) {
      log::warning("renderer: a render's callback threw: ", e.what());
    }
    std::lock_guard lock(mutex_);
    busy_ = false;
  }
  // stopping: what is still queued ends with an error
  std::deque<Job> left;
  {
    std::lock_guard lock(mutex_);
    left.swap(queue_);
  }
  for (Job& job : left) {
    RenderResult result;
    result.error = "the renderer stopped";
    result.scene = std::move(job.scene);
    try {
      job.done(std::move(result));
    } catch (const std::exception&) {}
  }
  gl_->close();
}

void Renderer::ensure_context(const std::shared_ptr<const mjModel>& model, int width, int height) {
  Gl& gl = *gl_;
  if (gl.con_made && gl.con_model == model && width <= gl.con_width && height <= gl.con_height)
    return;
  // the largest image asked so far, so that cameras of several sizes do not remake it
  width = std::max(width, gl.con_width);
  height = std::max(height, gl.con_height);
  if (gl.con_made) mjr_freeContext(&gl.con);
  gl.con_made = false;
  gl.con_model.reset();
  // MuJoCo sizes its offscreen buffer from the model: a shallow copy says how large
  mjModel sized = *model;
  sized.vis.global.offwidth = width;
  sized.vis.global.offheight = height;
  mjr_defaultContext(&gl.con);
  try {
    mjr_makeContext(&sized, &gl.con, mjFONTSCALE_50);
  } catch (...) {
    mjr_freeContext(&gl.con);
    throw;
  }
  gl.con_made = true;
  gl.con_model = model;
  gl.con_width = width;
  gl.con_height = height;
  mjr_setBuffer(mjFB_OFFSCREEN, &gl.con);
  if (gl.con.currentBuffer != mjFB_OFFSCREEN)
    throw std::runtime_error("MuJoCo made no offscreen framebuffer");
}

void Renderer::render_job(Job& job, RenderResult& result) {
  SceneCopy& scene = *job.scene;
  const CameraView& view = scene.view();
  const int w = view.width, h = view.height;
  ensure_context(scene.model(), w, h);
  mjr_setBuffer(mjFB_OFFSCREEN, &gl_->con);
  const mjrRect viewport{0, 0, w, h};
  mjr_render(viewport, scene.scene(), &gl_->con);

  const std::size_t pixels = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  std::vector<std::uint8_t> rgb(job.want_rgb ? 3 * pixels : 0);
  std::vector<float> depth(job.want_depth ? pixels : 0);
  mjr_readPixels(job.want_rgb ? rgb.data() : nullptr, job.want_depth ? depth.data() : nullptr,
                 viewport, &gl_->con);

  // OpenGL's rows go bottom up; images top down
  const auto row_bytes = static_cast<std::size_t>(w) * 3;
  if (job.want_rgb) {
    result.rgb.resize(rgb.size());
    for (int y = 0; y < h; ++y)
      std::memcpy(&result.rgb[static_cast<std::size_t>(y) * row_bytes],
                  &rgb[static_cast<std::size_t>(h - 1 - y) * row_bytes], row_bytes);
  }
  if (job.want_depth) {
    // the depth buffer holds d = f (z - n) / (z (f - n)) for a point at distance z along
    // the optical axis (OpenGL's perspective projection): z = n f / (f - d (f - n));
    // d = 1 is the far plane, where nothing was drawn
    const double n = view.near_clip, f = view.far_clip;
    result.depth.resize(pixels);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double d = depth[static_cast<std::size_t>(h - 1 - y) * w + x];
        result.depth[static_cast<std::size_t>(y) * w + x] =
            d >= 1.0 ? 0.0f : static_cast<float>(n * f / (f - d * (f - n)));
      }
  }
  result.width = w;
  result.height = h;
}

std::vector<std::vector<double>> intrinsic_matrix(const CameraView& view) {
  const double fy = view.height / 2.0 / std::tan(view.fovy * M_PI / 360.0);
  const double fx = fy;  // square pixels
  return {{fx, 0, view.width / 2.0}, {0, fy, view.height / 2.0}, {0, 0, 1}};
}

}  // namespace simgate::sim
