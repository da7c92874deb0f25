// `simgate snapshot` (see commands.h, docs/cli.md): a picture of the scene, written as a
// PNG file. Against a running simulation it calls `simulation get_snapshot` through the
// transport the client options name (as `call` does); with --config or --model it builds
// the deployment here, as `check` does (no transport listens), and renders its initial
// state with the same Snapshotter the service uses.
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "commands.h"
#include "simgate/core/base64.h"
#include "simgate/core/errors.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/image_codec.h"
#include "simgate/sim/snapshot.h"

namespace simgate::gateway {

namespace {

// "640x480" -> (640, 480), each from 1 to the service's limit
std::pair<long long, long long> parse_size(const std::string& text) {
  const auto x = text.find_first_of("xX");
  if (x != std::string::npos) {
    try {
      std::size_t used_w = 0, used_h = 0;
      const std::string w = text.substr(0, x), h = text.substr(x + 1);
      const long long width = std::stoll(w, &used_w), height = std::stoll(h, &used_h);
      if (used_w == w.size() && used_h == h.size() && width >= 1 && height >= 1 &&
          width <= sim::SnapshotOptions::k_max_size && height <= sim::SnapshotOptions::k_max_size)
        return {width, height};
    } catch (const std::exception&) {}
  }
  throw UsageError("--size: expected WIDTHxHEIGHT in pixels, each an integer from 1 to " +
                   std::to_string(sim::SnapshotOptions::k_max_size) + " (e.g. 640x480), found '" +
                   text + "'");
}

// OUT must be a file in an existing directory; checked before anything is rendered.
void check_output(const std::string& out) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(out, ec))
    throw UsageError("OUT: '" + out + "' is a directory; expected a file name (out.png)");
  const fs::path dir = fs::absolute(out, ec).parent_path();
  if (!fs::is_directory(dir, ec))
    throw std::runtime_error("cannot write '" + out + "': no directory " + dir.string());
  if (access(dir.c_str(), W_OK) != 0)
    throw std::runtime_error("cannot write '" + out + "': " + std::strerror(errno) + " (" +
                             dir.string() + ")");
}

// Writes the PNG whole, then renames it into place: OUT is never half written.
void write_png(const std::string& out, const std::vector<std::uint8_t>& png) {
  static const std::uint8_t k_signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (png.size() < 8 || std::memcmp(png.data(), k_signature, 8) != 0)
    throw std::runtime_error("the image received is not a PNG file");
  const std::string tmp = out + ".tmp" + std::to_string(getpid());
  {
    std::ofstream file(tmp, std::ios::binary | std::ios::trunc);
    if (!file) throw std::runtime_error("cannot write '" + out + "': " + std::strerror(errno));
    file.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
    file.close();
    if (!file) {
      std::filesystem::remove(tmp);
      throw std::runtime_error("cannot write '" + out + "': " + std::strerror(errno));
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    throw std::runtime_error("cannot write '" + out + "': " + ec.message());
  }
}

// The record's image, decoded and written; one line on stdout saying what was written.
int save(const SnapshotArgs& args, const json& record) {
  if (!record.is_object() || !record.contains("image") || !record["image"].is_string())
    throw std::runtime_error("simulation get_snapshot answered no image: " +
                             record.dump().substr(0, 200));
  std::vector<std::uint8_t> png;
  try {
    png = base64_decode(record["image"].get<std::string>());
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("the image received is not valid base64: ") + e.what());
  }
  write_png(args.out, png);
  std::cout << args.out << ": " << record.value("width", 0) << "x" << record.value("height", 0)
            << " PNG, " << png.size() << " bytes, camera "
            << record.value("camera", std::string("?")) << ", sim time "
            << record.value("timestamp", 0.0) << " s\n";
  return 0;
}

}  // namespace

int cmd_snapshot(const SnapshotArgs& args) {
  const auto [width, height] = parse_size(args.size);
  const bool offline = !args.scene.config.empty() || args.scene.model;
  if (offline &&
      (args.client.host || args.client.port || args.client.domain || args.client.partition ||
       args.client.dds_config || args.client.token || args.client.transport != "socket"))
    throw UsageError(
        "either --config/--model (render the scene here) or the client options (ask a running "
        "simulation), not both");
  check_output(args.out);
  const std::string camera = args.camera.value_or("");

  if (!offline) {
    std::chrono::milliseconds timeout{};
    auto client = connect_client(args.client, timeout);
    const json params = {{"camera", camera}, {"width", width}, {"height", height}};
    Outcome outcome = client->call("simulation", "get_snapshot", params, timeout);
    if (outcome.status != Status::success) {
      std::cerr << "simgate: " << to_string(outcome.status) << ": "
                << (!outcome.message.empty() ? outcome.message
                    : outcome.value          ? outcome.value->dump()
                                             : "")
                << "\n";
      return 1;
    }
    return save(args, outcome.value.value_or(json()));
  }

  // no gateway: the deployment built here, its initial state rendered
  double seconds = 0;
  try {
    seconds = std::stod(args.client.timeout);
  } catch (const std::exception&) {}
  if (!(seconds > 0))
    throw UsageError("--timeout: expected a positive number of seconds, found '" +
                     args.client.timeout + "'");
  ConfigErrors errors;
  const Deployment deployment = load_deployment_args(args.scene, errors);
  GatewayOptions options;
  options.check_only = true;  // nothing listens
  options.plugin_dirs = args.scene.plugin_dirs;
  const sim::ComponentRegistry registry = sim::builtin_registry();
  const std::unique_ptr<Gateway> gateway =
      build_gateway(args.scene, deployment, registry, options, std::move(errors));
  sim::Snapshotter snapshotter(gateway->simulation());
  const json record = snapshotter.take(
      {camera, width, height}, std::chrono::milliseconds(static_cast<long long>(seconds * 1000)));
  return save(args, record);
}

}  // namespace simgate::gateway
