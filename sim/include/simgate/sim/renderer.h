// simgate/sim/renderer.h — MuJoCo's renderer, headless: offscreen images of the simulation.
//
// Terms:
//  - Renderer: one OpenGL context (a GlContext, gl_context.h: EGL, Mesa's surfaceless
//    platform when there, else the default display; desktop OpenGL, no surface), and the
//    one render thread that owns it. Every GL call (mjr_*) runs on that thread.
//    One per process (Renderer::shared()), started on first use, stopped when the last
//    holder lets it go.
//  - CameraView: where a camera is and what it sees (pose, vertical field of view, clipping
//    planes, image size), computed under the simulation lock.
//  - SceneCopy: an mjvScene holding the geoms and lights of one state of the simulation as
//    seen from one view, with the model copy it was made from. Filled under the simulation
//    lock (update(): mjv_addGeoms, mjv_makeLights, mjv_updateSkin: copies, no rendering),
//    then handed to the render thread, which renders it without the lock and never reads
//    mjData or the live mjModel.
//  - Model copies: mjr_makeContext uploads meshes, textures and height fields of a model;
//    the render thread makes its context from a copy (mj_copyModel, made under the lock by
//    model_copy(); copies of equal models are shared) and remakes it when a scene of
//    another model (a spawn, a delete) or a larger image comes.
//
// No GL: when no EGL display or context can be made, unavailable() says why, and every
// render ends with that reason; nothing else is affected. The environment variable
// SIMGATE_RENDERER_UNAVAILABLE, when set, keeps the renderer from trying EGL and is the
// reason given (to switch rendering off, and to test that path).
//
// Threads: model_copy() and SceneCopy::update() on the simulation thread under the lock;
// render() from any thread (it queues); callbacks run on the render thread.
#ifndef SIMGATE_SIM_RENDERER_H_
#define SIMGATE_SIM_RENDERER_H_

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <mujoco/mujoco.h>

namespace simgate::sim {

// Where a camera is and what it sees, in the world frame.
struct CameraView {
  double position[3] = {0, 0, 0};
  double forward[3] = {1, 0, 0};  // unit, the optical axis
  double up[3] = {0, 0, 1};       // unit, orthogonal to forward: the image's up
  double fovy = 45;               // vertical field of view, degrees
  double near_clip = 0.01;        // m
  double far_clip = 100;          // m
  int width = 256;                // pixels
  int height = 256;               // pixels
};

// One state of the simulation as seen from a view, ready to render off the lock.
class SceneCopy {
 public:
  // Allocates the scene for `model` (a model_copy()); sim thread.
  explicit SceneCopy(std::shared_ptr<const mjModel> model);
  ~SceneCopy();
  SceneCopy(const SceneCopy&) = delete;
  SceneCopy& operator=(const SceneCopy&) = delete;

  // Copies the geoms, lights and skins of (m, d) seen from `view`; m must be the model
  // this copy was made for (equal to model()). Under the simulation lock.
  void update(const mjModel* m, mjData* d, const CameraView& view, double timestamp);

  const std::shared_ptr<const mjModel>& model() const { return model_; }
  const CameraView& view() const { return view_; }
  double timestamp() const { return timestamp_; }
  mjvScene* scene() { return &scene_; }

 private:
  std::shared_ptr<const mjModel> model_;  // the copy the scene's geoms refer to
  mjvScene scene_;                        // owned, freed with mjv_freeScene
  mjvOption option_;                      // MuJoCo's defaults (no decorations drawn)
  CameraView view_;                       // of the last update()
  double timestamp_ = 0;                  // simulated time of the state copied
};

// What one render produced.
struct RenderResult {
  std::string error;                 // non-empty: the render failed, and why
  int width = 0, height = 0;         // pixels
  std::vector<std::uint8_t> rgb;     // 3 bytes per pixel, top row first (empty unless asked)
  std::vector<float> depth;          // m along the optical axis, top row first, 0 where nothing
                                     // is hit within far_clip (empty unless asked)
  CameraView view;                   // as rendered
  double timestamp = 0;              // simulated time of the state rendered
  std::unique_ptr<SceneCopy> scene;  // given back, for the next update()
};

class Renderer {
 public:
  using Callback = std::function<void(RenderResult)>;

  // The process's renderer, started (its thread, its EGL context) on the first call after
  // none was alive. Thread-safe.
  static std::shared_ptr<Renderer> shared();
  // Stops the thread: queued renders end with an error; frees the context.
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Why nothing can be rendered, or "" when a context was made. Waits (bounded) for the
  // render thread's attempt to make one.
  std::string unavailable();

  // A copy of `m` the render thread may use (equal models share one). Under the lock.
  std::shared_ptr<const mjModel> model_copy(const mjModel* m);

  // Queues a render of `scene`; `done` runs on the render thread with the result (or the
  // reason it failed), and gets the scene back. Never blocks on the render. `wanted`, when
  // given, is asked on the render thread when the render's turn comes: false (the request
  // it is for ended meanwhile: its client left or cancelled it) skips the rendering, and
  // `done` gets the error "abandoned...".
  void render(std::unique_ptr<SceneCopy> scene, bool want_rgb, bool want_depth, Callback done,
              std::function<bool()> wanted = {});

  // Renders completed so far, and renders skipped as abandoned (for statistics and tests).
  std::uint64_t renders() const;
  std::uint64_t abandoned() const;
  // Whether nothing is queued or being rendered now (its callback included): a test that
  // waits for the renders asked so far to come back waits for this, however slow a render is.
  bool idle() const;

 private:
  struct Job {
    std::unique_ptr<SceneCopy> scene;
    bool want_rgb = true;
    bool want_depth = false;
    Callback done;
    std::function<bool()> wanted;  // empty: always
  };
  struct Gl;  // the GlContext and the mjrContext: render thread only

  Renderer();
  void run();  // the render thread
  void render_job(Job& job, RenderResult& result);
  void ensure_context(const std::shared_ptr<const mjModel>& model, int width, int height);

  mutable std::mutex mutex_;                  // guards what follows up to thread_
  std::condition_variable wake_;              // a job, or stop
  std::condition_variable started_cv_;        // the thread tried to make a context
  bool started_ = false;                      // it did
  bool stop_ = false;                         // the destructor asks the thread to end
  std::string unavailable_;                   // why there is no context ("" when there is one)
  std::deque<Job> queue_;                     // renders waiting
  std::uint64_t renders_ = 0;                 // renders completed
  std::uint64_t abandoned_ = 0;               // renders skipped: nobody wanted them any more
  bool busy_ = false;                         // the render thread holds a job (see idle())
  std::mutex copy_mutex_;                     // guards last_copy_
  std::shared_ptr<const mjModel> last_copy_;  // the latest model_copy(), shared when equal
  std::unique_ptr<Gl> gl_;                    // render thread only
  std::thread thread_;                        // last: started after everything above
};

// Intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] of a view (pixels; square pixels;
// the principal point at the image's centre): fy = height / 2 / tan(fovy / 2).
std::vector<std::vector<double>> intrinsic_matrix(const CameraView& view);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_RENDERER_H_
