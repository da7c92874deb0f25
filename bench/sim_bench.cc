// sim_bench.cc — simgate_bench_sim: simulation speed, one mode per run (--mode), each printing
// one JSON object on stdout. This file is the command line and its dispatch; each mode lives
// in the file named beside it, whose header comment says how it measures.
//
// Modes (--mode):
//   bare     mj_step in a tight loop on --mjcf: the physics alone, the ceiling of any loop on
//            the scene; --copies worlds stepped by --threads threads (stepping_bench.cc).
//   gateway  the Gateway of --config, built as `simgate run` builds it, with a probe stamping
//            every step: steps/s, real-time factor, overruns and the jitter of the step
//            period; --until-stdin-closes and --record-dir for the harness (stepping_bench.cc).
//   sleep    the machine's timer baseline for that jitter: a loop with no work sleeping until
//            each period (stepping_bench.cc).
//   laser    issue #18's laser_scanner target: a 360-ray scan, the component's update against
//            a bare loop of the same mj_ray calls (laser_bench.cc).
//   humanoid issue #18's stepping target: Debian's humanoid with the generic components, the
//            gateway's loop against bare mj_step calls, step for step (stepping_bench.cc).
//   snapshot issue #19's snapshots: `simulation save_state` and `restore_state` on --mjcf
//            against mj_copyData (snapshot_bench.cc).
//   spawn    issue #19's spawn target: `simulation spawn_entity` and `delete_entity` of one
//            free body on --mjcf against the edit alone and a bare mj_loadXML
//            (snapshot_bench.cc).
//   progress issue #20's progress target: 100 concurrent JSON-RPC calls getting progress
//            reports at 1 kHz each, the real-time factor against the same calls without
//            progress, in alternating rounds for --duration seconds (progress_bench.cc).
//   streams  issue #21's stream targets: --calls components (50) streaming at 100 Hz on the
//            socket, JSON-RPC and (--dds) DDS transports at once, every stream read by a
//            client: the real-time factor and CPU against the same gateway without streams,
//            the latency from a step's end to a socket subscriber's read and the sync round
//            trip of the same run (stream_bench.cc).
//   camera_fps  issue #22's frame-rate target: frames/s of simgate's camera path (scene copy,
//            the Renderer's render thread, pixels read back; with and without the PNG record)
//            against a bare mjv_updateScene + mjr_render + mjr_readPixels loop on the same
//            kind of EGL context, 320x240 and 640x480, RGB and depth, on --mjcf seen from
//            --site (camera_bench.cc).
//   camera_rtf  issue #22's real-time-factor target: --config (config/rover.json) at real
//            time, --duration seconds without and then with a JSON-RPC subscriber to
//            --camera's image stream (camera_bench.cc).
//   web_poses  issue #23's browser target: --config (config/demo.json, the web app's) at
//            real time, --duration seconds without and then with --calls WebSocket clients
//            (20 browser pages) receiving the body poses at --frequency (60 Hz) (web_bench.cc).
//   foxglove_rtf  issue #38's Foxglove target: --mjcf (bench/pendulums50.xml) on the foxglove
//            transport at real time, --duration seconds without and then with --calls Foxglove
//            clients (4) receiving /tf at --frequency (60 Hz) and a 640x480 camera at 10 Hz
//            (foxglove_bench.cc).
#include <iostream>
#include <string>

#include "bench_util.h"
#include "camera_bench.h"
#include "foxglove_bench.h"
#include "laser_bench.h"
#include "progress_bench.h"
#include "snapshot_bench.h"
#include "stepping_bench.h"
#include "stream_bench.h"
#include "web_bench.h"

using simgate::bench::json;

int main(int argc, char** argv) {
  CLI::App app{"Simulation speed: the gateway's step loop against a bare mj_step loop.",
               "simgate_bench_sim"};
  std::string mode, mjcf, config, record_dir;
  double factor = 0, duration = 2;
  bool until_stdin = false;
  double round_s = 1;
  int calls = 100;
  bool dds = false;
  simgate::bench::CameraFpsOptions camera_fps;
  std::string camera = "rover.camera";
  double frequency = 60;
  int copies = 1, threads = 1;
  app.add_option("--copies", copies, "bare: worlds of the model stepped")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--threads", threads, "bare: threads stepping them")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--mode", mode,
                 "bare, sleep, gateway, laser, humanoid, snapshot, spawn, progress, streams, "
                 "camera_fps, camera_rtf, web_poses or foxglove_rtf "
                 "(see the source's header)")
      ->required()
      ->check(CLI::IsMember({"bare", "sleep", "gateway", "laser", "humanoid", "snapshot", "spawn",
                             "progress", "streams", "camera_fps", "camera_rtf", "web_poses",
                             "foxglove_rtf"}));
  app.add_option("--site", camera_fps.site, "camera_fps: the site the view is from")
      ->capture_default_str();
  app.add_option("--frames", camera_fps.frames,
                 "camera_fps: frames per side, size and kind, at most")
      ->capture_default_str();
  app.add_option("--batch", camera_fps.batch, "camera_fps: frames of one side in a row")
      ->capture_default_str();
  app.add_option("--camera", camera, "camera_rtf: the camera component whose stream is subscribed")
      ->capture_default_str();
  app.add_option("--frequency", frequency,
                 "web_poses, foxglove_rtf: the body poses' samples per simulated second")
      ->capture_default_str();
  app.add_flag("--dds", dds, "streams: the DDS transport streams too");
  app.add_option("--round", round_s, "progress: simulated seconds each call runs")
      ->capture_default_str();
  app.add_option("--calls", calls,
                 "progress: concurrent calls, one connection each; streams: components; web_poses: "
                 "WebSocket clients; foxglove_rtf: Foxglove clients")
      ->capture_default_str();
  app.add_option(
      "--mjcf", mjcf,
      "bare, sleep, snapshot, spawn, progress, streams, camera_fps, foxglove_rtf: the MJCF "
      "scene; "
      "humanoid: another "
      "humanoid.xml");
  app.add_option("--config", config, "gateway, camera_rtf, web_poses: the deployment file");
  app.add_option("--realtime-factor", factor, "gateway: pacing (0 = as fast as possible)")
      ->capture_default_str();
  app.add_option("--duration", duration,
                 "seconds to run (camera_fps: per side, size and kind, at most)")
      ->capture_default_str();
  app.add_flag("--until-stdin-closes", until_stdin,
               "gateway: run until standard input closes instead");
  app.add_option("--record-dir", record_dir,
                 "gateway: let clients record into DIR (simulation start_recording NAME)");
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  if ((mode == "bare" || mode == "sleep" || mode == "snapshot" || mode == "spawn" ||
       mode == "progress" || mode == "streams" || mode == "camera_fps" || mode == "foxglove_rtf") &&
      mjcf.empty()) {
    std::cerr << "simgate_bench_sim: --mode " << mode << " needs --mjcf PATH\n";
    return 2;
  }
  if ((mode == "gateway" || mode == "camera_rtf" || mode == "web_poses") && config.empty()) {
    std::cerr << "simgate_bench_sim: --mode " << mode << " needs --config PATH\n";
    return 2;
  }
  try {
    json out;
    if (mode == "bare") {
      out = simgate::bench::run_bare(mjcf, duration, copies, threads);
    } else if (mode == "sleep") {
      out = simgate::bench::run_sleep(mjcf, duration);
    } else if (mode == "laser") {
      out = simgate::bench::run_laser(duration);
    } else if (mode == "humanoid") {
      out = simgate::bench::run_humanoid(mjcf, duration);
    } else if (mode == "snapshot") {
      out = simgate::bench::run_snapshot(mjcf, duration);
    } else if (mode == "spawn") {
      out = simgate::bench::run_spawn(mjcf, duration);
    } else if (mode == "progress") {
      out = simgate::bench::run_progress(mjcf, duration, round_s, calls);
    } else if (mode == "streams") {
      out = simgate::bench::run_streams(mjcf, duration, calls, 2000, dds);
    } else if (mode == "camera_fps") {
      camera_fps.mjcf = mjcf;
      camera_fps.seconds = duration;
      out = simgate::bench::run_camera_fps(camera_fps);
    } else if (mode == "camera_rtf") {
      out = simgate::bench::run_camera_rtf(config, camera, duration);
    } else if (mode == "web_poses") {
      out = simgate::bench::run_web_poses(config, calls, frequency, duration);
    } else if (mode == "foxglove_rtf") {
      out = simgate::bench::run_foxglove_rtf(mjcf, calls, frequency, duration);
    } else {
      out = simgate::bench::run_gateway(config, factor, duration, until_stdin, record_dir);
    }
    std::cout << out.dump() << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_sim: " << e.what() << "\n";
    return 1;
  }
}
