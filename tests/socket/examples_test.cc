// The seeds' standalone examples (docs/examples), run as real processes on an ephemeral
// port and driven over TCP like a telnet user would.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <vector>

#include "simgate/client/socket_client.h"

extern char** environ;

namespace simgate::socket::test {
namespace {

using namespace std::chrono_literals;
using client::SocketClient;
using Clock = std::chrono::steady_clock;

// A running example: started on port 0, its port read from its first line of output,
// stopped with SIGTERM (then SIGKILL) at the end.
class ExampleProcess {
 public:
  ExampleProcess(const std::string& path, std::vector<std::string> args) {
    int out[2];
    if (::pipe2(out, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    args.insert(args.begin(), path);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    // the plugin of this build, whatever the environment says
    std::vector<std::string> env_strings{"SIMGATE_PLUGIN_PATH=" SIMGATE_TEST_PLUGIN_DIR};
    for (char** e = environ; *e; ++e)
      if (std::string(*e).rfind("SIMGATE_PLUGIN_PATH=", 0) != 0) env_strings.emplace_back(*e);
    std::vector<char*> envp;
    for (auto& e : env_strings) envp.push_back(e.data());
    envp.push_back(nullptr);
    int rc = posix_spawn(&pid_, path.c_str(), &actions, nullptr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    out_ = out[0];
    if (rc != 0) throw std::runtime_error("cannot start " + path);
  }
  ~ExampleProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      int status = 0;
      auto deadline = Clock::now() + 10s;
      while (::waitpid(pid_, &status, WNOHANG) == 0) {
        if (Clock::now() > deadline) {
          ::kill(pid_, SIGKILL);
          ::waitpid(pid_, &status, 0);
          break;
        }
        ::usleep(10000);  // polling a child's exit; not synchronisation of the test itself
      }
    }
    if (out_ >= 0) ::close(out_);
  }

  // The next line of the example's stdout (deadline: 15 s).
  std::string read_line() {
    auto deadline = Clock::now() + 15s;
    for (;;) {
      auto nl = buffer_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buffer_.substr(0, nl);
        buffer_.erase(0, nl + 1);
        return line;
      }
      auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) throw std::runtime_error("the example printed nothing in time");
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, int(left)) <= 0) continue;
      char chunk[4096];
      ssize_t n = ::read(out_, chunk, sizeof chunk);
      if (n <= 0) throw std::runtime_error("the example exited early");
      buffer_.append(chunk, std::size_t(n));
    }
  }

  // Reads "listening on tcp://127.0.0.1:<port>" and returns the port.
  std::uint16_t port() {
    std::string line = read_line();
    EXPECT_THAT(line, ::testing::StartsWith("listening on tcp://127.0.0.1:"));
    return static_cast<std::uint16_t>(std::stoi(line.substr(line.rfind(':') + 1)));
  }

 private:
  pid_t pid_ = -1;      // the example process
  int out_ = -1;        // its stdout
  std::string buffer_;  // stdout bytes not yet returned as lines
};

TEST(Examples, AddAnswersTheSeedRequest) {
  ExampleProcess add(SIMGATE_EXAMPLE_ADD, {"--port", "0"});
  SocketClient c("127.0.0.1", add.port());
  c.send_line("req1 test_component add (1,2)");
  EXPECT_EQ(c.read_line(15s).value_or("<nothing>"), "req1 SUCCESS 3");
  c.send_line("req2 test_component add [1.0, 1.6]");
  EXPECT_EQ(c.read_line(15s).value_or("<nothing>"), "req2 SUCCESS 2.6");
}

TEST(Examples, AddWithTheDocumentedSuccessWord) {
  ExampleProcess add(SIMGATE_EXAMPLE_ADD, {"--port", "0", "--success-word", "OK"});
  SocketClient c("127.0.0.1", add.port());
  c.send_line("req1 test_component add (1,2)");
  EXPECT_EQ(c.read_line(15s).value_or("<nothing>"), "req1 OK 3");
}

TEST(Examples, ComputeFinishesAboutFiveSecondsLater) {
  ExampleProcess compute(SIMGATE_EXAMPLE_COMPUTE, {"--port", "0"});
  SocketClient c("127.0.0.1", compute.port());
  c.send_line("req2 test_component compute (5,)");
  // nothing until the computation is over; other requests are still served meanwhile
  c.send_line("req3 test_component nope");
  EXPECT_THAT(c.read_line(15s).value_or("<nothing>"),
              ::testing::HasSubstr("has not been registered"));
  EXPECT_EQ(c.read_line(15s).value_or("<nothing>"), "req2 SUCCESS \"done!\"");
  // it counted down once per second on the way
  EXPECT_EQ(compute.read_line(), "Value is now 4");
}

TEST(Examples, PymorseCallsTheAddExample) {
  if (::access("/usr/bin/python3", X_OK) != 0 ||
      std::system("/usr/bin/python3 -W ignore -c 'import pymorse' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "pymorse is not installed";
  ExampleProcess add(SIMGATE_EXAMPLE_ADD, {"--port", "0"});
  std::uint16_t port = add.port();
  std::string script =
      "import pymorse\n"
      "m = pymorse.Morse('127.0.0.1', " +
      std::to_string(port) +
      ")\n"
      "assert m.rpc('test_component', 'add', 1, 2) == 3\n"
      "try:\n"
      "    m.rpc('test_component', 'add', 1)\n"
      "    raise SystemExit('no TypeError')\n"
      "except TypeError:\n"
      "    pass\n"
      "m.close(wait_publishers=False)\n";
  std::string command = "timeout 60 /usr/bin/python3 -W ignore -c \"" + script + "\"";
  EXPECT_EQ(std::system(command.c_str()), 0);
}

}  // namespace
}  // namespace simgate::socket::test
