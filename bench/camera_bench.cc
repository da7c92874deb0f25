// camera_bench.cc — issue #22's camera targets (camera_bench.h):
//
// camera_fps: frames per second of simgate's camera path against a bare MuJoCo loop, for
// each image size (320x240, 640x480) and kind (RGB; depth), on --mjcf (the rover's room) seen
// from the site the rover's cameras use (config/rover.json: `laser`), the state fixed.
//   - bare:  on a GlContext (gl_context.h, the same kind of EGL context the Renderer makes),
//            made on this thread: mjv_updateScene + mjr_render + mjr_readPixels into a
//            buffer (RGB; or depth, linearised to metres as the Renderer does), one frame
//            after the other. MuJoCo's free camera placed at the view (same position,
//            direction, field of view and clipping planes).
//   - raw:   simgate's path: SceneCopy::update on this thread (what a camera does under the
//            simulation lock), Renderer::render (the render thread renders, reads the pixels,
//            flips the rows, linearises depth), this thread waiting for the result: the
//            pixels a stream hands to a typed transport.
//   - png:   the same, with the image record made on the render thread as get_image and
//            capture make it (PNG, base64).
// The three alternate in batches of --batch frames, the order rotating every round, until
// each has --frames frames or --duration seconds; after warm-up frames. Figures: frames/s
// per side (median of its batches) and raw/bare, png/bare (median of the rounds' ratios,
// with min and max); the scene copy's µs; the mean absolute difference between the bare
// loop's and the Renderer's last images (the same view: a few levels at most).
//
// camera_rtf: a Gateway built from --config (config/rover.json, its transports moved to
// ephemeral loopback ports) as `simgate run` builds it, at real-time pacing. Phase 1, --duration
// seconds, nobody subscribed (the camera renders nothing); phase 2, a JSON-RPC client
// subscribed to the camera's stream (rpc.subscribe; 10 Hz, 320x240 in rover.json: each sample
// rendered on the render thread and encoded as a PNG on the transport's thread), timed from
// its first sample for --duration seconds. Real-time factor of each phase (steps x timestep /
// wall), samples received per second, the gateway's CPU per second of each phase.
//
// Threads: camera_fps runs on the calling thread (plus the Renderer's); camera_rtf runs the
// gateway's loop on the calling thread, its client on another with a blocking socket.
#include "camera_bench.h"

#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <functional>
#include <future>
#include <stdexcept>
#include <thread>

#include <mujoco/mujoco.h>

#include "simgate/core/log.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/gl_context.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/render_support.h"
#include "simgate/sim/renderer.h"

namespace simgate::bench {
namespace {

namespace sim = simgate::sim;

json spread(const std::vector<double>& v) {
  if (v.empty()) return nullptr;
  return {{"median", median(v)},
          {"min", *std::min_element(v.begin(), v.end())},
          {"max", *std::max_element(v.begin(), v.end())},
          {"n", v.size()}};
}

// Linearised depth, as the Renderer does: d = f (z - n) / (z (f - n)) -> z; 0 at the far plane.
inline float linear_depth(double d, double n, double f) {
  return d >= 1.0 ? 0.0f : static_cast<float>(n * f / (f - d * (f - n)));
}

// The bare loop: MuJoCo's own calls on a context current on this thread.
class BareLoop {
 public:
  BareLoop(const mjModel* m, const sim::CameraView& view) : view_(view) {
    // the model sized for the image, the free camera's field of view the view's
    model_ = mj_copyModel(nullptr, m);
    model_->vis.global.offwidth = view.width;
    model_->vis.global.offheight = view.height;
    model_->vis.global.fovy = static_cast<float>(view.fovy);
    mjr_defaultContext(&con_);
    mjr_makeContext(model_, &con_, mjFONTSCALE_50);
    mjr_setBuffer(mjFB_OFFSCREEN, &con_);
    if (con_.currentBuffer != mjFB_OFFSCREEN)
      throw std::runtime_error("MuJoCo made no offscreen framebuffer");
    mjv_defaultScene(&scene_);
    mjv_makeScene(model_, &scene_, 2 * m->ngeom + 2 * m->ntendon + 100);
    mjv_defaultOption(&option_);
    mjv_defaultPerturb(&perturb_);
    // MuJoCo's free camera at the view: looking along forward (azimuth, elevation), up the
    // world's z tilted with it
    mjv_defaultCamera(&camera_);
    camera_.type = mjCAMERA_FREE;
    camera_.distance = 1;
    for (int i = 0; i < 3; ++i) camera_.lookat[i] = view.position[i] + view.forward[i];
    camera_.azimuth = std::atan2(view.forward[1], view.forward[0]) * 180 / M_PI;
    camera_.elevation = std::asin(std::clamp(view.forward[2], -1.0, 1.0)) * 180 / M_PI;
    const std::size_t pixels =
        static_cast<std::size_t>(view.width) * static_cast<std::size_t>(view.height);
    rgb_.resize(3 * pixels);
    raw_depth_.resize(pixels);
    depth_.resize(pixels);
  }
  ~BareLoop() {
    mjv_freeScene(&scene_);
    mjr_freeContext(&con_);
    mj_deleteModel(model_);
  }
  BareLoop(const BareLoop&) = delete;
  BareLoop& operator=(const BareLoop&) = delete;

  void frame(const mjData* d, bool depth) {
    const mjrRect viewport{0, 0, view_.width, view_.height};
    mjv_updateScene(model_, const_cast<mjData*>(d), &option_, &perturb_, &camera_, mjCAT_ALL,
                    &scene_);
    mjr_render(viewport, &scene_, &con_);
    if (!depth) {
      mjr_readPixels(rgb_.data(), nullptr, viewport, &con_);
      return;
    }
    mjr_readPixels(nullptr, raw_depth_.data(), viewport, &con_);
    const double n = model_->vis.map.znear * model_->stat.extent,
                 f = model_->vis.map.zfar * model_->stat.extent;
    for (std::size_t i = 0; i < depth_.size(); ++i) depth_[i] = linear_depth(raw_depth_[i], n, f);
  }
  // The last image, rows bottom first (OpenGL's).
  const std::vector<std::uint8_t>& rgb() const { return rgb_; }
  const std::vector<float>& depth() const { return depth_; }

 private:
  sim::CameraView view_;
  mjModel* model_ = nullptr;  // a copy, sized for the image
  mjrContext con_;
  mjvScene scene_;
  mjvOption option_;
  mjvPerturb perturb_;
  mjvCamera camera_;
  std::vector<std::uint8_t> rgb_;
  std::vector<float> raw_depth_, depth_;
};

// simgate's path: a scene copy rendered by the Renderer, this thread waiting for it.
class RendererLoop {
 public:
  RendererLoop(sim::Renderer& renderer, const mjModel* m)
      : renderer_(renderer), scene_(std::make_unique<sim::SceneCopy>(renderer.model_copy(m))) {}

  // One frame of `view`; `record`: the image record too (PNG, base64) on the render thread.
  void frame(const mjModel* m, mjData* d, const sim::CameraView& view, bool depth, bool record) {
    const auto t0 = Clock::now();
    scene_->update(m, d, view, d->time);
    copy_ns_.push_back(ns_between(t0, Clock::now()));
    std::promise<sim::RenderResult> done;
    std::size_t bytes = 0;
    renderer_.render(
        std::move(scene_), !depth, depth, [&done, &bytes, depth, record](sim::RenderResult r) {
          try {
            if (record && r.error.empty()) {
              const json image = depth ? sim::depth_image_record(r) : sim::rgb_image_record(r);
              bytes = image.at("image").get_ref<const std::string&>().size();
            }
          } catch (const std::exception& e) {
            r.error = std::string("image record: ") + e.what();
          }
          done.set_value(std::move(r));
        });
    result_ = done.get_future().get();
    scene_ = std::move(result_.scene);
    if (!result_.error.empty()) throw std::runtime_error("Renderer: " + result_.error);
    if (record) record_bytes_ = bytes;
  }
  const sim::RenderResult& last() const { return result_; }
  std::size_t record_bytes() const { return record_bytes_; }
  std::vector<std::int64_t>& copy_ns() { return copy_ns_; }

 private:
  sim::Renderer& renderer_;
  std::unique_ptr<sim::SceneCopy> scene_;  // handed to the render thread and back
  sim::RenderResult result_;               // of the last frame
  std::size_t record_bytes_ = 0;           // base64 PNG of the last recorded frame
  std::vector<std::int64_t> copy_ns_;      // SceneCopy::update times
};

// Mean absolute difference between the bare loop's last image (rows bottom first) and the
// Renderer's (top first): levels of 0..255 for RGB, metres for depth.
double difference(const BareLoop& bare, const sim::RenderResult& r, bool depth) {
  const int w = r.width, h = r.height;
  double sum = 0;
  std::size_t n = 0;
  for (int y = 0; y < h; ++y) {
    const std::size_t bare_row = static_cast<std::size_t>(h - 1 - y) * w,
                      row = static_cast<std::size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      if (depth) {
        sum += std::fabs(bare.depth()[bare_row + x] - r.depth[row + x]);
        ++n;
      } else {
        for (int c = 0; c < 3; ++c, ++n)
          sum += std::abs(int(bare.rgb()[3 * (bare_row + x) + c]) - int(r.rgb[3 * (row + x) + c]));
      }
    }
  }
  return n ? sum / static_cast<double>(n) : 0;
}

}  // namespace

json run_camera_fps(const CameraFpsOptions& o) {
  log::set_level(log::Level::warning);
  // both contexts first: no figure without both
  std::string why;
  std::unique_ptr<sim::GlContext> gl = sim::GlContext::make(why);
  if (!gl) return {{"mode", "camera_fps"}, {"skipped", "no EGL context for the bare loop: " + why}};
  std::shared_ptr<sim::Renderer> renderer = sim::Renderer::shared();
  if (std::string r = renderer->unavailable(); !r.empty())
    return {{"mode", "camera_fps"}, {"skipped", "the Renderer has no context: " + r}};

  char error[1000] = "";
  mjModel* m = mj_loadXML(o.mjcf.c_str(), nullptr, error, sizeof error);
  if (!m) throw std::runtime_error("MJCF '" + o.mjcf + "': " + error);
  mjData* d = mj_makeData(m);
  // a settled state (the rover on its wheels), fixed from here
  for (int i = 0; i < 200; ++i) mj_step(m, d);
  mj_forward(m, d);
  // the view: the rover cameras' site, as a Camera component computes it (cameras.cc)
  sim::CameraView base;
  const int site = mj_name2id(m, mjOBJ_SITE, o.site.c_str());
  if (site < 0) throw std::runtime_error("MJCF '" + o.mjcf + "' has no site '" + o.site + "'");
  sim::frame_pose(base, d->site_xpos + 3 * site, d->site_xmat + 9 * site);
  base.fovy = m->vis.global.fovy;  // 45: the camera's default and MuJoCo's free camera's
  base.near_clip = m->vis.map.znear * m->stat.extent;
  base.far_clip = m->vis.map.zfar * m->stat.extent;

  json rows = json::array();
  RendererLoop simgate(*renderer, m);
  for (const auto& [width, height] : o.sizes) {
    sim::CameraView view = base;
    view.width = width;
    view.height = height;
    BareLoop bare(m, view);
    for (const bool depth : {false, true}) {
      if (depth && !o.depth) continue;
      // the three sides; warm-up frames first (shaders, the Renderer's context at this size)
      auto bare_frame = [&] { bare.frame(d, depth); };
      auto raw_frame = [&] { simgate.frame(m, d, view, depth, false); };
      auto png_frame = [&] { simgate.frame(m, d, view, depth, true); };
      const std::function<void()> sides[3] = {bare_frame, raw_frame, png_frame};
      for (const auto& side : sides)
        for (int i = 0; i < 3; ++i) side();
      const double pixel_difference = difference(bare, simgate.last(), depth);
      simgate.copy_ns().clear();

      std::vector<double> fps[3], raw_ratio, png_ratio;
      double elapsed[3] = {0, 0, 0};
      int frames = 0, round = 0;
      while (round < 2 ||
             (frames < o.frames && *std::max_element(elapsed, elapsed + 3) < o.seconds)) {
        double batch_fps[3] = {0, 0, 0};
        for (int k = 0; k < 3; ++k) {
          const int s = (round + k) % 3;
          const auto t0 = Clock::now();
          for (int i = 0; i < o.batch; ++i) sides[s]();
          const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
          elapsed[s] += seconds;
          batch_fps[s] = o.batch / seconds;
          fps[s].push_back(batch_fps[s]);
        }
        raw_ratio.push_back(batch_fps[1] / batch_fps[0]);
        png_ratio.push_back(batch_fps[2] / batch_fps[0]);
        frames += o.batch;
        ++round;
      }
      std::vector<std::int64_t> copy_ns = simgate.copy_ns();
      rows.push_back({{"width", width},
                      {"height", height},
                      {"kind", depth ? "depth" : "rgb"},
                      {"rounds", round},
                      {"frames_per_side", frames},
                      {"bare_fps", median(fps[0])},
                      {"raw_fps", median(fps[1])},
                      {"png_fps", median(fps[2])},
                      {"raw_ratio", spread(raw_ratio)},
                      {"png_ratio", spread(png_ratio)},
                      {"scene_copy", summarize_us(std::move(copy_ns))},
                      {"png_base64_bytes", simgate.record_bytes()},
                      {"mean_abs_difference", pixel_difference}});
    }
  }
  mj_deleteData(d);
  mj_deleteModel(m);
  return {{"mode", "camera_fps"},
          {"model", o.mjcf},
          {"site", o.site},
          {"gl_platform", gl->platform()},
          {"gl_renderer", gl->gl_renderer()},
          {"batch", o.batch},
          {"rows", rows}};
}

// ---- camera_rtf ----------------------------------------------------------------------------

namespace {

struct RtfPhase : RealtimePhase {  // cpu_s: the gateway's threads
  std::uint64_t samples = 0;       // rpc.sample notifications read
  std::uint64_t bytes = 0;         // their lines' bytes
};

}  // namespace

json run_camera_rtf(const std::string& config, const std::string& camera, double seconds) {
  namespace gw = simgate::gateway;
  log::set_level(log::Level::warning);
  {
    // no GL, no figure: the camera would render nothing and the phases would be equal
    std::shared_ptr<sim::Renderer> renderer = sim::Renderer::shared();
    if (std::string r = renderer->unavailable(); !r.empty())
      return {{"mode", "camera_rtf"}, {"skipped", r}};
  }
  json document = gw::load_config_document(config);
  for (auto& [name, transport] : document.at("transports").items()) {
    json& options = transport["options"];
    options["host"] = "127.0.0.1";
    options["port"] = 0;
    if (options.contains("stream_port")) options["stream_port"] = 0;
  }
  document["log_level"] = "warning";
  const gw::Deployment deployment =
      gw::parse_deployment(document, std::filesystem::path(config).parent_path().string(), config);
  const auto registry = sim::builtin_registry();
  gw::Gateway gateway(deployment, registry, {});
  gateway.start();
  const std::uint16_t port = endpoint_port(gateway.endpoints().at("jsonrpc").at(0));
  const double timestep = gateway.simulation().timestep();

  RtfPhase without, with;
  json first_sample, subscribed;
  std::string error;
  std::thread client([&] {
    int fd = -1;
    try {
      auto measure = [&](RealtimePhase& phase, auto&& during) {
        measure_realtime_phase(
            phase, seconds, timestep, [&] { return gateway.simulation().steps(); }, during);
      };
      // phase 1: nobody subscribed
      measure(without, [](Clock::time_point end) { std::this_thread::sleep_until(end); });

      // phase 2: a JSON-RPC subscriber, timed from its first sample
      fd = connect_loopback(port);
      const std::string subscribe =
          R"({"jsonrpc":"2.0","id":1,"method":"rpc.subscribe","params":{"component":")" + camera +
          "\"}}\n";
      if (::send(fd, subscribe.data(), subscribe.size(), MSG_NOSIGNAL) !=
          static_cast<ssize_t>(subscribe.size()))
        throw std::runtime_error("send failed");
      std::string text;
      std::vector<char> buffer(1 << 20);
      // reads lines until `end`; counts the samples into `phase` (when given); false at the end
      auto read_until = [&](Clock::time_point end, RtfPhase* phase, bool stop_at_sample) {
        for (;;) {
          std::size_t begin = 0;
          for (std::size_t nl; (nl = text.find('\n', begin)) != std::string::npos; begin = nl + 1) {
            const std::string_view line(text.data() + begin, nl - begin);
            const bool sample =
                line.substr(0, 200).find("\"rpc.sample\"") != std::string_view::npos;
            if (!sample && line.find("\"error\"") != std::string_view::npos)
              throw std::runtime_error("rpc.subscribe " + camera + ": " +
                                       std::string(line.substr(0, 400)));
            if (!sample && line.find("\"result\"") != std::string_view::npos)
              subscribed = json::parse(line);
            if (sample && phase) {
              ++phase->samples;
              phase->bytes += line.size() + 1;
            }
            if (sample && stop_at_sample) {
              first_sample = json::parse(line);
              text.erase(0, nl + 1);
              return true;
            }
          }
          text.erase(0, begin);
          if (Clock::now() >= end) return false;
          pollfd p{fd, POLLIN, 0};
          if (::poll(&p, 1, 20) <= 0) continue;
          const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), 0);
          if (n <= 0) throw std::runtime_error("the JSON-RPC connection closed");
          text.append(buffer.data(), static_cast<std::size_t>(n));
        }
      };
      if (!read_until(Clock::now() + std::chrono::seconds(60), nullptr, true))
        throw std::runtime_error("no sample of " + camera + "'s stream within 60 s");
      measure(with, [&](Clock::time_point end) { read_until(end, &with, false); });
    } catch (const std::exception& e) {
      error = e.what();
    }
    if (fd >= 0) ::close(fd);
    gateway.stop();
  });
  gateway.run();
  client.join();
  gateway.shutdown();
  if (!error.empty()) throw std::runtime_error(error);
  const json& data = first_sample.at("params").at("data");
  auto phase_json = [](const RtfPhase& p) {
    return json{{"wall_s", p.wall_s},
                {"realtime_factor", p.realtime_factor},
                {"gateway_cpu_per_s", p.cpu_s / p.wall_s},
                {"samples", p.samples},
                {"samples_per_s", static_cast<double>(p.samples) / p.wall_s},
                {"mean_sample_bytes",
                 p.samples ? static_cast<double>(p.bytes) / static_cast<double>(p.samples) : 0.0}};
  };
  return {{"mode", "camera_rtf"},
          {"config", config},
          {"camera", camera},
          {"timestep", timestep},
          {"image",
           {{"width", data.at("width")},
            {"height", data.at("height")},
            {"encoding", data.at("encoding")}}},
          {"frequency_hz", subscribed.at("result").at("stream").at("frequency")},
          {"without", phase_json(without)},
          {"with", phase_json(with)},
          {"ratio", with.realtime_factor / without.realtime_factor}};
}

}  // namespace simgate::bench
