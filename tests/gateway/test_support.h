// Helpers for the gateway tests: configs in temporary files, a line-oriented TCP client
// for the MORSE socket protocol (loopback only, every read has a deadline), and a child
// process runner with a deadline.
#ifndef SIMGATE_TESTS_GATEWAY_TEST_SUPPORT_H_
#define SIMGATE_TESTS_GATEWAY_TEST_SUPPORT_H_

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

extern char** environ;

namespace simgate::gateway::testing {

using json = nlohmann::json;
using namespace std::chrono_literals;

inline std::string source_path(const std::string& rel) {
  return std::string(SIMGATE_SOURCE_DIR) + "/" + rel;
}
inline std::string simgate_binary() { return std::string(SIMGATE_BINARY_DIR) + "/bin/simgate"; }

// A unique temporary directory, removed with the object.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "simgate-test-XXXXXX").string();
    std::vector<char> buf(pattern.begin(), pattern.end());
    buf.push_back('\0');
    if (!mkdtemp(buf.data())) throw std::runtime_error("mkdtemp failed");
    path_ = buf.data();
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return path_ + "/" + name; }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(file(name)) << text;
    return file(name);
  }

 private:
  std::string path_;  // the directory
};

// The demo deployment on ephemeral ports, with an absolute scene path.
inline json demo_config(double factor = 1.0) {
  json c = json::parse(std::ifstream(source_path("config/demo.json")));
  c["scene"]["mjcf"] = source_path("config/scenes/demo.xml");
  c["scene"]["realtime_factor"] = factor;
  c["transports"]["socket"]["options"]["port"] = 0;
  c["transports"]["socket"]["options"]["stream_port"] = 0;  // its datastreams too
  c["transports"]["websocket"]["options"]["port"] = 0;      // the web app's
  c["transports"]["foxglove"]["options"]["port"] = 0;
  c["transports"]["mcp"]["options"]["port"] = 0;
  c["log_level"] = "warning";
  return c;
}

// The demo with its socket transport only (no websocket, no web app, no foxglove, no mcp): for tests
// that count transports or read which transports serve a component.
inline json socket_demo_config(double factor = 1.0) {
  json c = demo_config(factor);
  c["transports"].erase("websocket");
  c["transports"].erase("foxglove");
  c["transports"].erase("mcp");
  const auto without_websocket = [](const json& transports) {
    json kept = json::array();
    for (const auto& t : transports)
      if (t != "websocket" && t != "foxglove" && t != "mcp") kept.push_back(t);
    return kept;
  };
  for (auto& [pattern, transports] : c["services"].items())
    transports = without_websocket(transports);
  // a stream rule is a list of transports or {"transports": [...], "frequency": Hz}; one
  // left with no transport goes
  json streams = json::object();
  const json rules = c.value("streams", json::object());
  for (const auto& [component, rule] : rules.items()) {
    json kept = rule.is_object() ? rule : json{{"transports", rule}};
    kept["transports"] = without_websocket(kept["transports"]);
    if (kept["transports"].empty()) continue;
    streams[component] = rule.is_object() ? kept : kept["transports"];
  }
  if (c.contains("streams")) c["streams"] = std::move(streams);
  return c;
}

// A TCP connection to 127.0.0.1:`port` (its descriptor); `receive_buffer` (bytes, 0: the
// system's) is set before connecting, so that it is the window the client offers.
inline int connect_loopback(int port, int receive_buffer = 0) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (receive_buffer > 0)
    ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    throw std::runtime_error("connect to 127.0.0.1:" + std::to_string(port) + " failed");
  }
  return fd;
}

// The entry of `component` in `simulation get_stream_statistics`' answer (null: none).
inline json stream_of(const json& stats, const std::string& component) {
  for (const auto& s : stats)
    if (s["component"] == component) return s;
  return nullptr;
}

// One TCP connection speaking lines.
class LineClient {
 public:
  explicit LineClient(int port) : fd_(connect_loopback(port)) {}
  ~LineClient() { ::close(fd_); }
  LineClient(const LineClient&) = delete;
  LineClient& operator=(const LineClient&) = delete;

  void send(const std::string& text) {
    std::size_t sent = 0;
    while (sent < text.size()) {
      ssize_t n = ::send(fd_, text.data() + sent, text.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) throw std::runtime_error("send failed");
      sent += static_cast<std::size_t>(n);
    }
  }
  // The next line (without '\n'), or nullopt on timeout or end of stream.
  std::optional<std::string> read_line(std::chrono::milliseconds timeout = 20s) {
    auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      auto nl = buffer_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buffer_.substr(0, nl);
        buffer_.erase(0, nl + 1);
        return line;
      }
      auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      char chunk[4096];
      ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
      if (n <= 0) {
        closed_ = true;
        return std::nullopt;
      }
      buffer_.append(chunk, static_cast<std::size_t>(n));
    }
  }
  // Sends "<id> <request>" and returns the answer line for that id (other ids are kept).
  std::string request(const std::string& id, const std::string& request,
                      std::chrono::milliseconds timeout = 20s) {
    send(id + " " + request + "\n");
    return wait_for(id, timeout);
  }
  std::string wait_for(const std::string& id, std::chrono::milliseconds timeout = 20s) {
    for (auto it = others_.begin(); it != others_.end(); ++it)
      if (it->rfind(id + " ", 0) == 0) {
        std::string line = *it;
        others_.erase(it);
        return line;
      }
    auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      auto line = read_line(std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now()));
      if (!line) break;
      if (line->rfind(id + " ", 0) == 0) return *line;
      others_.push_back(*line);
    }
    return "<no answer for " + id + ">";
  }
  // True once the server closed the connection (waits up to `timeout`).
  bool closed_by_server(std::chrono::milliseconds timeout = 20s) {
    auto deadline = std::chrono::steady_clock::now() + timeout;
    while (!closed_ && std::chrono::steady_clock::now() < deadline) {
      auto line = read_line(std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now()));
      if (line) others_.push_back(*line);
    }
    return closed_;
  }
  const std::vector<std::string>& other_lines() const { return others_; }

 private:
  int fd_ = -1;                      // the connection
  std::string buffer_;               // bytes after the last complete line
  std::vector<std::string> others_;  // lines read while waiting for another id
  bool closed_ = false;              // end of stream seen
};

// One JSON-RPC call on `c`, one at a time (the next line is its response); null on timeout.
inline json rpc(LineClient& c, int id, const std::string& method, json params = nullptr) {
  json request{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}};
  if (!params.is_null()) request["params"] = std::move(params);
  c.send(request.dump() + "\n");
  auto line = c.read_line();
  return line ? json::parse(*line, nullptr, false) : json();
}

// The JSON payload of "<id> STATUS <json>".
inline json payload(const std::string& line) {
  auto first = line.find(' ');
  auto second = line.find(' ', first + 1);
  if (second == std::string::npos) return nullptr;
  return json::parse(line.substr(second + 1));
}

inline std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// An environment variable set (or unset, with nullopt) for the life of the object, then
// restored: the processes started meanwhile inherit it.
class ScopedEnv {
 public:
  ScopedEnv(std::string name, const std::optional<std::string>& value) : name_(std::move(name)) {
    if (const char* old = std::getenv(name_.c_str())) old_ = old;
    if (value) {
      ::setenv(name_.c_str(), value->c_str(), 1);
    } else {
      ::unsetenv(name_.c_str());
    }
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_.c_str(), old_->c_str(), 1);
    } else {
      ::unsetenv(name_.c_str());
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  std::string name_;                // the variable
  std::optional<std::string> old_;  // its value before, if it had one
};

// A config's TCP transports (socket, jsonrpc, websocket plugins) requiring the token that
// `token_env` holds, from every client: loopback ones too, which the tests are.
inline void require_token(json& config, const std::string& token_env) {
  for (auto& [name, transport] : config["transports"].items()) {
    const std::string plugin = transport.value("plugin", name);
    if (plugin == "socket" || plugin == "jsonrpc" || plugin == "websocket")
      transport["options"]["auth"] = {{"token_env", token_env}, {"loopback", true}};
  }
}

// A child process with stdout/stderr in files.
class Process {
 public:
  Process(std::vector<std::string> args, const std::string& out_dir)
      : out_(out_dir + "/stdout" + std::to_string(next_id())),
        err_(out_dir + "/stderr" + std::to_string(next_id())) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~Process() {
    if (pid_ > 0 && !exit_code_) {
      ::kill(pid_, SIGKILL);
      int status;
      ::waitpid(pid_, &status, 0);
    }
  }
  // Exit code (128 + signal for a signal), or nullopt if still running after `timeout`.
  std::optional<int> wait(std::chrono::milliseconds timeout = 60s) {
    if (exit_code_) return exit_code_;
    auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      int status = 0;
      pid_t r = ::waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        return exit_code_;
      }
      std::this_thread::sleep_for(10ms);  // polling a child's state; bounded by the deadline
    }
    return std::nullopt;
  }
  void signal(int sig) { ::kill(pid_, sig); }
  static int next_id() {
    static std::atomic<int> id{0};
    return ++id;
  }
  std::string out() const { return read_file(out_); }
  std::string err() const { return read_file(err_); }

 private:
  pid_t pid_ = -1;                // the child
  std::string out_, err_;         // capture files
  std::optional<int> exit_code_;  // once reaped
};

// Runs simgate to completion.
inline std::pair<int, std::string> run_simgate(std::vector<std::string> args, const TempDir& dir) {
  args.insert(args.begin(), simgate_binary());
  Process p(args, dir.file(""));
  auto code = p.wait(60s);
  return {code.value_or(-1), p.out() + p.err()};
}

// Waits (bounded) for a file to appear; returns its contents or "".
inline std::string wait_for_file(const std::string& path, std::chrono::milliseconds timeout = 60s) {
  auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (std::filesystem::exists(path)) return read_file(path);
    std::this_thread::sleep_for(10ms);  // polling for a file another process writes
  }
  return "";
}

inline int port_of(const std::string& endpoint) {
  return std::stoi(endpoint.substr(endpoint.rfind(':') + 1));
}

// The outcome of a `simgate` run, stdout and stderr apart.
struct CliRun {
  int code = -1;                               // exit code (-1: still running at the deadline)
  std::string out;                             // stdout
  std::string err;                             // stderr
  std::chrono::steady_clock::duration took{};  // from start to exit
};

// Runs the simgate executable with `args` in `dir`, for at most `timeout`.
inline CliRun run_cli(std::vector<std::string> args, const TempDir& dir,
                      std::chrono::milliseconds timeout = 60s) {
  args.insert(args.begin(), simgate_binary());
  const auto started = std::chrono::steady_clock::now();
  Process p(args, dir.file(""));
  const auto code = p.wait(timeout);
  return {code.value_or(-1), p.out(), p.err(), std::chrono::steady_clock::now() - started};
}

}  // namespace simgate::gateway::testing

#endif  // SIMGATE_TESTS_GATEWAY_TEST_SUPPORT_H_
