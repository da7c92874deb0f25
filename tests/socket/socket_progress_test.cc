// Progress lines on the socket transport (issue #20), over real TCP: a connection that sent
// `<id> simgate progress` gets `<id> PROGRESS <json>` for each report of its async requests,
// then their final reply; a connection that did not gets exactly MORSE's replies, byte for
// byte; a connection that does not read loses progress lines (64 KiB unsent), never a reply.
#include <string>
#include <vector>

#include "socket_test_fixture.h"

namespace simgate::socket::test {
namespace {

class SocketProgress : public SocketFixture {
 protected:
  void SetUp() override { start_server({{"progress_interval_ms", 0}}); }  // every report

  // Sends `line` (an async request) and waits until it has started: the reply to a sync
  // request sent after it on the same connection follows its start.
  static void start(SocketClient& c, const std::string& line) {
    c.send_line(line);
    ASSERT_EQ(roundtrip(c, "b test echo [0]"), "b SUCCESS 0");
  }

  // job hold(token): async, finished by `job release(value)`; `job report(value)` is a
  // progress report of the held request (true when it reached a client), `job flood(n,
  // size)` n reports of a string of `size` bytes (how many reached a client)
  void register_more(RequestManager& rm) override {
    auto held = std::make_shared<Completion>();
    rm.register_async_service("job",
                              [held](Completion c, json /*token*/) {
                                *held = c;
                                return true;
                              },
                              "hold", {"token"});
    rm.register_service("job", [held](json value) { return held->progress(std::move(value)); },
                        "report", {"value"});
    rm.register_service("job",
                        [held](int n, int size) {
                          int passed = 0;
                          for (int i = 0; i < n; ++i)
                            passed +=
                                held->progress(json(std::string(std::size_t(size), 'p'))) ? 1 : 0;
                          return passed;
                        },
                        "flood", {"n", "size"});
    rm.register_service("job",
                        [held](json value) {
                          bool done = (*held)(Status::success, value);
                          *held = Completion();
                          return done;
                        },
                        "release", {"value"});
  }
};

TEST_F(SocketProgress, AConnectionThatOptedInGetsProgressLinesThenTheReply) {
  auto client = connect();
  EXPECT_EQ(roundtrip(*client, "p1 simgate progress"), "p1 SUCCESS");
  start(*client, "a1 job hold [\"t\"]");
  auto control = connect();
  EXPECT_EQ(roundtrip(*control, "c1 job report [1]"), "c1 SUCCESS true");
  EXPECT_EQ(roundtrip(*control, "c2 job report [{\"left\": 2.5, \"name\": \"caf\\u00e9\"}]"),
            "c2 SUCCESS true");
  EXPECT_EQ(roundtrip(*control, "c3 job release [\"done\"]"), "c3 SUCCESS true");
  // MORSE's JSON: ", " and ": " separators, non-ASCII escaped
  EXPECT_EQ(next_line(*client), "a1 PROGRESS 1");
  EXPECT_EQ(next_line(*client), "a1 PROGRESS {\"left\": 2.5, \"name\": \"caf\\u00e9\"}");
  EXPECT_EQ(next_line(*client), "a1 SUCCESS \"done\"");
}

TEST_F(SocketProgress, AConnectionThatDidNotOptInGetsTheOldRepliesOnly) {
  auto client = connect();
  start(*client, "0 job hold [\"t\"]");
  auto control = connect();
  EXPECT_EQ(roundtrip(*control, "c1 job report [1]"), "c1 SUCCESS false");  // nobody asked
  EXPECT_EQ(roundtrip(*control, "c2 job release [\"done\"]"), "c2 SUCCESS true");
  EXPECT_EQ(next_line(*client), "0 SUCCESS \"done\"");
  // nothing else came: the next line is the answer to the next request
  EXPECT_EQ(roundtrip(*client, "1 test echo [2]"), "1 SUCCESS 2");
}

TEST_F(SocketProgress, OptingOutStopsTheLinesAndRequestsBeforeTheOptInGetNone) {
  auto client = connect();
  start(*client, "a1 job hold [\"t\"]");  // sent before opting in: no progress
  EXPECT_EQ(roundtrip(*client, "p1 simgate progress [true]"), "p1 SUCCESS");
  auto control = connect();
  EXPECT_EQ(roundtrip(*control, "c1 job report [1]"), "c1 SUCCESS false");
  EXPECT_EQ(roundtrip(*control, "c2 job release [1]"), "c2 SUCCESS true");
  EXPECT_EQ(next_line(*client), "a1 SUCCESS 1");
  EXPECT_EQ(roundtrip(*client, "p2 simgate progress (False,)"), "p2 SUCCESS");
  start(*client, "a2 job hold [\"t\"]");
  EXPECT_EQ(roundtrip(*control, "c3 job report [2]"), "c3 SUCCESS false");
  EXPECT_EQ(roundtrip(*control, "c4 job release [2]"), "c4 SUCCESS true");
  EXPECT_EQ(next_line(*client), "a2 SUCCESS 2");
}

TEST_F(SocketProgress, BadOptInParamsAreFailedInMorsesPhrases) {
  auto client = connect();
  EXPECT_EQ(roundtrip(*client, "p1 simgate progress [1]"),
            "p1 FAILED \"wrong parameter type for service simgate.progress: parameter 'on' expects "
            "boolean, got "
            "number 1\"");
  EXPECT_EQ(roundtrip(*client, "p2 simgate progress [true, false]"),
            "p2 FAILED \"wrong # of parameters for service simgate.progress: expected at most 1 "
            "(on), got 2\"");
  EXPECT_THAT(roundtrip(*client, "p3 simgate progress [tru"),
              ::testing::StartsWith("p3 FAILED \"Invalid request syntax"));
  // a bare value is the one parameter (before: "expected at most 1 (on), got 1")
  EXPECT_EQ(roundtrip(*client, "p4 simgate progress 7"),
            "p4 FAILED \"wrong parameter type for service simgate.progress: parameter 'on' expects "
            "boolean, got "
            "number 7\"");
  EXPECT_EQ(roundtrip(*client, "p5 simgate progress false"), "p5 SUCCESS");
  // the connection did not opt in
  start(*client, "a1 job hold [\"t\"]");
  auto control = connect();
  EXPECT_EQ(roundtrip(*control, "c1 job report [1]"), "c1 SUCCESS false");
  EXPECT_EQ(roundtrip(*control, "c2 job release [1]"), "c2 SUCCESS true");
  EXPECT_EQ(next_line(*client), "a1 SUCCESS 1");
}

TEST_F(SocketProgress, AClientThatDoesNotReadLosesProgressLinesNeverTheReply) {
  auto client = connect();
  EXPECT_EQ(roundtrip(*client, "p1 simgate progress"), "p1 SUCCESS");
  start(*client, "a1 job hold [\"t\"]");
  auto control = connect();
  // while the client reads nothing: 4 MiB of reports (512 of 8 KiB), far more than the
  // socket buffers and the 64 KiB the server queues before it drops them
  constexpr int k_reports = 512;
  EXPECT_EQ(roundtrip(*control, "c1 job flood [512, 8192]"),
            "c1 SUCCESS " + std::to_string(k_reports));
  EXPECT_EQ(roundtrip(*control, "c2 job release [\"done\"]"), "c2 SUCCESS true");
  // now it reads: some progress lines, then the reply, and then nothing more
  int progress_lines = 0;
  std::string line;
  for (int i = 0; i < k_reports + 2; ++i) {  // bounded: at most every report and the reply
    line = next_line(*client);
    if (line.rfind("a1 PROGRESS ", 0) != 0) break;
    ++progress_lines;
  }
  EXPECT_EQ(line, "a1 SUCCESS \"done\"");
  EXPECT_GE(progress_lines, 1);
  EXPECT_LT(progress_lines, k_reports + 1) << "every report was queued: none was dropped";
  EXPECT_EQ(roundtrip(*client, "e1 test echo [3]"), "e1 SUCCESS 3");
}

}  // namespace
}  // namespace simgate::socket::test
