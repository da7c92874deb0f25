// Golden transcripts of the socket transport over real TCP: every rule of the protocol.
// (Clients that leave, limits and options: socket_connections_test.cc; what both TCP
// transports share: tcp_transport_test.cc.)
#include <mutex>

#include "socket_test_fixture.h"

namespace simgate::socket::test {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::StartsWith;

class SocketTransport : public SocketFixture {
 protected:
  void SetUp() override { start_server(); }

  // Sync round trips on `c` for `duration` (at most `max_calls`): long enough for the
  // client to be alone (kit::ReadSplit::k_alone_after) and its socket read directly by the
  // polling I/O thread. Returns how many were answered right; stops at the first wrong one.
  static int call_back_to_back(SocketClient& c, const std::string& prefix,
                               std::chrono::milliseconds duration, int max_calls = 50'000) {
    const auto end = std::chrono::steady_clock::now() + duration;
    int ok = 0;
    for (int i = 0; i < max_calls && std::chrono::steady_clock::now() < end; ++i, ++ok) {
      const std::string id = prefix + std::to_string(i);
      if (roundtrip(c, id + " test_component add (" + std::to_string(i) + ", 1)") !=
          id + " SUCCESS " + std::to_string(i + 1))
        break;
    }
    return ok;
  }
};

// ---- calls and parameters

TEST_F(SocketTransport, SeedAddWithPythonTuple) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "req1 test_component add (1,2)"), "req1 SUCCESS 3");
}

TEST_F(SocketTransport, JsonArrayParamsLikePymorse) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "0 test_component add [1, 2]"), "0 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "1 test_component add [1.0, 1.6]"), "1 SUCCESS 2.6");
  EXPECT_EQ(roundtrip(*c, "2 test_component add [\"a\", \"b\"]"), "2 SUCCESS \"ab\"");
}

TEST_F(SocketTransport, PythonLiteralParams) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "r1 test_component add ('a', \"b\")"), "r1 SUCCESS \"ab\"");
  EXPECT_EQ(roundtrip(*c, "r2 test_component add ([1, 2], [3],)"), "r2 SUCCESS [1, 2, 3]");
  EXPECT_EQ(roundtrip(*c, "r3 test echo (True,)"), "r3 SUCCESS true");
  EXPECT_EQ(roundtrip(*c, "r4 test echo ({'k': (None, False)},)"),
            "r4 SUCCESS {\"k\": [null, false]}");
  EXPECT_EQ(roundtrip(*c, "r5 test echo (5,)"), "r5 SUCCESS 5");
  EXPECT_EQ(roundtrip(*c, "r6 test echo (5)"), "r6 SUCCESS 5");
}

TEST_F(SocketTransport, ObjectParamsAreNamedArguments) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "n1 test_component add {\"b\": 2, \"a\": 40}"), "n1 SUCCESS 42");
  EXPECT_EQ(roundtrip(*c, "n2 test_component add {'a': 'x', 'b': 'y'}"), "n2 SUCCESS \"xy\"");
}

TEST_F(SocketTransport, NoParamsEmptyListAndEmptyTupleCallWithoutArguments) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "e1 test ping"), "e1 SUCCESS \"pong\"");
  EXPECT_EQ(roundtrip(*c, "e2 test ping []"), "e2 SUCCESS \"pong\"");
  EXPECT_EQ(roundtrip(*c, "e3 test ping ()"), "e3 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, WhitespaceBetweenTokensCrLfAndSurroundingBlanks) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "w1  test_component  add  (1,2)"), "w1 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "w2\ttest_component\tadd\t(1,2)"), "w2 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "w3 \t test_component\t add \t[1, 2]"), "w3 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "   w4 test_component add (1,2)   "), "w4 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "w5 test_component add (1,2)\r"), "w5 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "w6 test ping\r"), "w6 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, BlankLinesAreIgnored) {
  auto c = connect();
  c->send_raw("\n\r\n   \n");
  EXPECT_EQ(roundtrip(*c, "b1 test ping"), "b1 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, FalsyResultsAreSent) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "f1 test echo (0,)"), "f1 SUCCESS 0");
  EXPECT_EQ(roundtrip(*c, "f2 test echo (False,)"), "f2 SUCCESS false");
  EXPECT_EQ(roundtrip(*c, "f3 test echo ('',)"), "f3 SUCCESS \"\"");
  EXPECT_EQ(roundtrip(*c, "f4 test echo ([],)"), "f4 SUCCESS []");
  EXPECT_EQ(roundtrip(*c, "f5 test echo ({},)"), "f5 SUCCESS {}");
  EXPECT_EQ(roundtrip(*c, "f6 test echo (0.0,)"), "f6 SUCCESS 0.0");
  EXPECT_EQ(roundtrip(*c, "f7 test_component add [0, 0]"), "f7 SUCCESS 0");
}

TEST_F(SocketTransport, NothingOrNullGivesBareSuccess) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "v1 test nothing"), "v1 SUCCESS");
  EXPECT_EQ(roundtrip(*c, "v2 test none []"), "v2 SUCCESS");
  EXPECT_EQ(roundtrip(*c, "v3 test echo (None,)"), "v3 SUCCESS");
}

TEST_F(SocketTransport, JsonIsWrittenLikePythonJsonDumps) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "j1 test echo ([1, 'x', {'a': 1.5}],)"),
            "j1 SUCCESS [1, \"x\", {\"a\": 1.5}]");
  EXPECT_EQ(roundtrip(*c, "j2 test echo ('caf\xc3\xa9 \xf0\x9f\x98\x80',)"),
            "j2 SUCCESS \"caf\\u00e9 \\ud83d\\ude00\"");
  EXPECT_EQ(roundtrip(*c, "j3 test echo ('a\\tb\\n\"',)"), "j3 SUCCESS \"a\\tb\\n\\\"\"");
  EXPECT_EQ(roundtrip(*c, "j4 test echo (1e-05,)"), "j4 SUCCESS 1e-05");
  EXPECT_EQ(roundtrip(*c, "j5 test echo (NaN,)"), "j5 SUCCESS NaN");
  EXPECT_EQ(roundtrip(*c, "j6 test echo (-Infinity,)"), "j6 SUCCESS -Infinity");
}

TEST_F(SocketTransport, IdIsEchoedVerbatim) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "some-ID_42.x test ping"), "some-ID_42.x SUCCESS \"pong\"");
  EXPECT_EQ(roundtrip(*c, "\xc3\xa9t\xc3\xa9 test ping"), "\xc3\xa9t\xc3\xa9 SUCCESS \"pong\"");
}

// ---- errors: MORSE's phrases, and the connection keeps working

TEST_F(SocketTransport, UnknownServiceOrComponentHasNotBeenRegistered) {
  auto c = connect();
  std::string unknown_service = roundtrip(*c, "u1 test_component nope (1,2)");
  EXPECT_THAT(
      unknown_service,
      StartsWith("u1 FAILED \"The request nope has not been registered in Socket service manager"));
  std::string unknown_component = roundtrip(*c, "u2 ghost add (1,2)");
  EXPECT_THAT(
      unknown_component,
      StartsWith("u2 FAILED \"The request add has not been registered in Socket service manager"));
  EXPECT_THAT(unknown_component, HasSubstr("ghost"));
  EXPECT_EQ(roundtrip(*c, "u3 test_component add (1,2)"), "u3 SUCCESS 3");
}

TEST_F(SocketTransport, ArityErrorsSayWrongNumberOfParameters) {
  auto c = connect();
  EXPECT_THAT(roundtrip(*c, "a1 test_component add (1,)"),
              AllOf(StartsWith("a1 FAILED \""), HasSubstr("wrong # of parameters")));
  EXPECT_THAT(roundtrip(*c, "a2 test_component add (1,2,3)"),
              AllOf(StartsWith("a2 FAILED \""), HasSubstr("wrong # of parameters")));
  EXPECT_THAT(roundtrip(*c, "a3 test_component add"),
              AllOf(StartsWith("a3 FAILED \""), HasSubstr("parameters expected")));
}

TEST_F(SocketTransport, TypeErrorsSayWrongParameterType) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "t1 test scale (2,)"), "t1 SUCCESS 4.0");
  EXPECT_THAT(
      roundtrip(*c, "t2 test scale ('two',)"),
      AllOf(StartsWith("t2 FAILED \""), HasSubstr("wrong parameter type"), HasSubstr("'x'")));
}

TEST_F(SocketTransport, BadParamsSyntaxSaysWhatAndWhere) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "p1 test_component add (1,2"),
            "p1 FAILED \"Invalid request syntax: error while parsing the parameters at column 27: "
            "expected ',' or ')' in tuple but found the end of the parameters\"");
  EXPECT_EQ(roundtrip(*c, "p2 test_component add (1, x)"),
            "p2 FAILED \"Invalid request syntax: error while parsing the parameters at column 27: "
            "unknown name 'x' (expected a number, a quoted string, True, False or None)\"");
  EXPECT_EQ(roundtrip(*c, "p3 test_component add [1, 2] extra"),
            "p3 FAILED \"Invalid request syntax: error while parsing the parameters at column 30: "
            "unexpected 'e' after the end of the parameters\"");
  EXPECT_EQ(roundtrip(*c, "p4 test echo ('abc"),
            "p4 FAILED \"Invalid request syntax: error while parsing the parameters at column 15: "
            "unterminated string\"");
  EXPECT_EQ(roundtrip(*c, "p5 test_component add (1,2)"), "p5 SUCCESS 3");
  // a refused line leaves nothing pending: its id is free at once
  EXPECT_EQ(roundtrip(*c, "p1 test_component add (1,2)"), "p1 SUCCESS 3");
}

TEST_F(SocketTransport, BareValuesAreRefusedWithTheListMeant) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "b1 test_component add 0.5 0.2"),
            "b1 FAILED \"Invalid request syntax: parameters must be a list, e.g. `[0.5, 0.2]`\"");
  EXPECT_EQ(roundtrip(*c, "b2 test_component add 'a', \"b\""),
            "b2 FAILED \"Invalid request syntax: parameters must be a list, e.g. `[\\\"a\\\", "
            "\\\"b\\\"]`\"");
  EXPECT_EQ(roundtrip(*c, "b3 test_component add [0.5, 0.2]"), "b3 SUCCESS 0.7");
}

TEST_F(SocketTransport, ScalarParamsAreRefusedByTheCore) {
  auto c = connect();
  EXPECT_THAT(roundtrip(*c, "s1 test echo 5"),
              AllOf(StartsWith("s1 FAILED \""), HasSubstr("must be a list")));
}

TEST_F(SocketTransport, ServiceErrorMessageIsTheFailedPayload) {
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "x1 test fail ('Our human cannot walk at negative speed!',)"),
            "x1 FAILED \"Our human cannot walk at negative speed!\"");
}

TEST_F(SocketTransport, OtherExceptionsFailTheRequestNotTheServer) {
  auto c = connect();
  EXPECT_THAT(roundtrip(*c, "x2 test crash"), AllOf(StartsWith("x2 FAILED \""), HasSubstr("boom")));
  EXPECT_EQ(roundtrip(*c, "x3 test ping"), "x3 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, MalformedLinesGetFailedAndTheConnectionLives) {
  auto c = connect();
  EXPECT_THAT(roundtrip(*c, "m1"), StartsWith("m1 FAILED \"Malformed request! "));
  EXPECT_THAT(roundtrip(*c, "m2 test_component"),
              StartsWith("m2 FAILED \"Malformed request! missing the service"));
  // binary garbage: unknown component (printable replacement in the message)
  static const char garbage[] = "m3 \x01\x02\x7f\x00zz yy";
  EXPECT_THAT(roundtrip(*c, std::string(garbage, sizeof garbage - 1)),
              StartsWith("m3 FAILED \"The request yy has not been registered"));
  // invalid UTF-8 in a name
  EXPECT_EQ(
      roundtrip(*c, "m4 te\xff\xfest ping"),
      "m4 FAILED \"Invalid request syntax: the component name is not valid UTF-8 (column 6)\"");
  // invalid UTF-8 inside a string parameter
  EXPECT_THAT(roundtrip(*c, "m5 test echo ('\xc3\x28',)"),
              StartsWith("m5 FAILED \"Invalid request syntax"));
  EXPECT_EQ(roundtrip(*c, "m6 test_component add (1,2)"), "m6 SUCCESS 3");
}

TEST_F(SocketTransport, MalformedLinesFromOneClientDoNotDisturbAnother) {
  auto hostile = connect();
  auto good = connect();
  static const char garbage[] = "\xff\xfe\x00\x01 garbage\n\x80\n \t\n";
  hostile->send_raw(std::string(garbage, sizeof garbage - 1));
  EXPECT_EQ(roundtrip(*good, "g1 test_component add (1,2)"), "g1 SUCCESS 3");
  EXPECT_THAT(next_line(*hostile), HasSubstr("FAILED"));
}

// ---- framing

TEST_F(SocketTransport, RequestSplitOverManySegments) {
  auto c = connect();
  const std::string line = "split1 test_component add (1,2)\n";
  for (char ch : line) c->send_raw(std::string(1, ch));  // TCP_NODELAY: one segment per byte
  EXPECT_EQ(next_line(*c), "split1 SUCCESS 3");
  c->send_raw("split2 test_comp");
  c->send_raw("onent add [40,");
  c->send_raw(" 2]\r");
  c->send_raw("\n");
  EXPECT_EQ(next_line(*c), "split2 SUCCESS 42");
}

TEST_F(SocketTransport, SeveralRequestsInOneSegment) {
  auto c = connect();
  c->send_raw("k1 test_component add (1,2)\nk2 test_component add (3,4)\r\nk3 test ping\n");
  EXPECT_EQ(next_line(*c), "k1 SUCCESS 3");
  EXPECT_EQ(next_line(*c), "k2 SUCCESS 7");
  EXPECT_EQ(next_line(*c), "k3 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, ErrorRepliesKeepTheOrderOfSyncRequests) {
  auto c = connect();
  c->send_raw("o1 test_component add (1,2)\no2\no3 test_component add (1,\no4 test ping\n");
  EXPECT_EQ(next_line(*c), "o1 SUCCESS 3");
  EXPECT_THAT(next_line(*c), StartsWith("o2 FAILED \"Malformed request!"));
  EXPECT_THAT(next_line(*c), StartsWith("o3 FAILED \"Invalid request syntax"));
  EXPECT_EQ(next_line(*c), "o4 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, AnErrorReplyInTheMiddleOfAReadLosesNoLaterLine) {
  // An error after a valid request makes the transport answer that request at once, in the
  // middle of the read. Answering must not start the next read while this read's lines are
  // still being handled: that read would land in the same buffer (a bug that lost lines).
  auto c = connect();
  std::string burst = "e1 test_component add (1,2)\ne2\n";
  constexpr int k_lines = 3000;  // ~100 KB: several reads, more bytes waiting behind each
  for (int i = 0; i < k_lines; ++i) {
    burst += "x" + std::to_string(i) + " test_component add (" + std::to_string(i) + ", 1)\n";
    if (i % 500 == 0) burst += "e" + std::to_string(i) + "\n";  // more errors, later reads
  }
  c->send_raw(burst);
  std::size_t errors = 0;
  int expected = 0;
  EXPECT_EQ(next_line(*c), "e1 SUCCESS 3");
  EXPECT_THAT(next_line(*c), StartsWith("e2 FAILED"));
  while (expected < k_lines) {
    std::string line = next_line(*c);
    ASSERT_FALSE(line.empty()) << "no reply for x" << expected;
    if (line[0] == 'e') {
      ++errors;
      continue;
    }
    ASSERT_EQ(line, "x" + std::to_string(expected) + " SUCCESS " + std::to_string(expected + 1));
    ++expected;
  }
  EXPECT_EQ(errors, std::size_t(k_lines / 500));
}

TEST_F(SocketTransport, RepliesKeepTheirOrderWhenTheSimulationIsBusy) {
  // the simulation lock is held (a long step): requests and the error replies behind them
  // are queued, then answered in order by the simulation thread
  auto c = connect();
  {
    std::lock_guard stepping(*manager_->gate());
    c->send_raw("b1 test_component add (1,2)\nb2\nb3 test_component add (1,\nb4 test ping\n");
    // give the I/O thread time to read them while the lock is held (if it reads later, the
    // requests run on it instead: the order must hold either way)
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_EQ(next_line(*c), "b1 SUCCESS 3");
  EXPECT_THAT(next_line(*c), StartsWith("b2 FAILED \"Malformed request!"));
  EXPECT_THAT(next_line(*c), StartsWith("b3 FAILED \"Invalid request syntax"));
  EXPECT_EQ(next_line(*c), "b4 SUCCESS \"pong\"");
  // and afterwards requests run at once again, in the call objects the queued ones left
  c->send_raw("b5 test_component add (2,2)\nb6 test echo [[7, 8]]\nb7 test ping\n");
  EXPECT_EQ(next_line(*c), "b5 SUCCESS 4");
  EXPECT_EQ(next_line(*c), "b6 SUCCESS [7, 8]");
  EXPECT_EQ(next_line(*c), "b7 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, CallObjectsReusedFromReadToReadCarryNothingOver) {
  // the transport refills the call objects (and parameter arrays) of earlier reads: a
  // later, shorter or differently shaped request must not see any of the earlier one
  auto c = connect();
  c->send_raw(
      "r1 test echo [[[1, 2, 3], 'long string argument that needs the heap', {'k': [4]}]]\n"
      "r2 test_component add (1, 2)\n"
      "r3 test echo [5]\n");
  EXPECT_EQ(next_line(*c),
            "r1 SUCCESS [[1, 2, 3], \"long string argument that needs the heap\", {\"k\": [4]}]");
  EXPECT_EQ(next_line(*c), "r2 SUCCESS 3");
  EXPECT_EQ(next_line(*c), "r3 SUCCESS 5");
  EXPECT_EQ(roundtrip(*c, "r4 test echo [[]]"), "r4 SUCCESS []");
  EXPECT_EQ(roundtrip(*c, "r5 test ping"), "r5 SUCCESS \"pong\"");
  EXPECT_EQ(roundtrip(*c, "r6 test_component add [2, 5]"), "r6 SUCCESS 7");
  EXPECT_THAT(roundtrip(*c, "r7 test echo [1"), StartsWith("r7 FAILED \"Invalid request syntax"));
  EXPECT_EQ(roundtrip(*c, "r8 test echo ('x',)"), "r8 SUCCESS \"x\"");
  // numbers stay in the call object and are overwritten in place by the next parse
  EXPECT_EQ(roundtrip(*c, "r9 test_component add [1, 2]"), "r9 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "r10 test echo [7]"), "r10 SUCCESS 7");
  EXPECT_EQ(roundtrip(*c, "r11 test_component add [3, 4]"), "r11 SUCCESS 7");
  EXPECT_THAT(roundtrip(*c, "r12 test_component add [5, x]"),
              StartsWith("r12 FAILED \"Invalid request syntax"));
  EXPECT_EQ(roundtrip(*c, "r13 test echo [[9]]"), "r13 SUCCESS [9]");
  EXPECT_EQ(roundtrip(*c, "r14 test echo [{'a': 1}]"), "r14 SUCCESS {\"a\": 1}");
  EXPECT_EQ(roundtrip(*c, "r15 test_component add {'a': 1, 'b': 2}"), "r15 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "r16 test_component add [1, 1]"), "r16 SUCCESS 2");
  // an integer overwritten in place only when the kept element is a signed integer
  EXPECT_EQ(roundtrip(*c, "r17 test echo [18446744073709551615]"),
            "r17 SUCCESS 18446744073709551615");
  EXPECT_EQ(roundtrip(*c, "r18 test echo [-5]"), "r18 SUCCESS -5");
  EXPECT_EQ(roundtrip(*c, "r19 test echo [2.5]"), "r19 SUCCESS 2.5");
  EXPECT_EQ(roundtrip(*c, "r20 test echo [7]"), "r20 SUCCESS 7");
  EXPECT_EQ(roundtrip(*c, "r21 test echo [True]"), "r21 SUCCESS true");
  EXPECT_EQ(roundtrip(*c, "r22 test echo [8]"), "r22 SUCCESS 8");
}

TEST_F(SocketTransport, LargeBurstThenEndOfInputGetsEveryReply) {
  // a pipelining client's reads are read on while bytes wait and answered together; the
  // end of input may come in one of those reads: every request is still answered, in order
  auto c = connect();
  constexpr int k_lines = 3000;  // ~100 KB: many reads
  std::string burst;
  for (int i = 0; i < k_lines; ++i)
    burst += "b" + std::to_string(i) + " test_component add (" + std::to_string(i) + ", 1)\n";
  c->send_raw(burst);
  c->shutdown_send();
  for (int i = 0; i < k_lines; ++i)
    ASSERT_EQ(next_line(*c), "b" + std::to_string(i) + " SUCCESS " + std::to_string(i + 1));
  EXPECT_THROW(c->read_line(10s), client::ClientError);  // then the server closes
}

TEST_F(SocketTransport, LastRequestIsAnsweredAfterClientShutsDownSending) {
  auto c = connect();
  c->send_raw("eof1 test_component add (1,2)\neof2 test_component add (2,2)");  // no final '\n'
  c->shutdown_send();
  EXPECT_EQ(next_line(*c), "eof1 SUCCESS 3");
  EXPECT_EQ(next_line(*c), "eof2 SUCCESS 4");
  EXPECT_THROW(c->read_line(10s), client::ClientError);  // then the server closes
  EXPECT_TRUE(c->closed());
}

// ---- a lone client, read directly by the polling I/O thread (idle_spin.h)

TEST_F(SocketTransport, ALoneClientCallingBackToBackAndPausingIsAlwaysAnswered) {
  // after each pause, far longer than the polling window, the I/O thread has slept: it
  // must have handed the socket back to the event loop, or the next request goes unread
  auto c = connect();
  for (int round = 0; round < 3; ++round) {
    const std::string prefix = "r" + std::to_string(round) + "-";
    EXPECT_GT(call_back_to_back(*c, prefix, 20ms), 0);
    std::this_thread::sleep_for(5ms);
    EXPECT_EQ(roundtrip(*c, prefix + "after test ping"), prefix + "after SUCCESS \"pong\"");
  }
  // end of input found by a direct read: the last request is answered, then the close
  EXPECT_GT(call_back_to_back(*c, "last-", 20ms), 0);
  c->send_raw("end test_component add (2, 2)");
  c->shutdown_send();
  EXPECT_EQ(next_line(*c), "end SUCCESS 4");
  EXPECT_THROW(c->read_line(10s), client::ClientError);
}

TEST_F(SocketTransport, OthersAreServedWhileALoneClientIsReadDirectly) {
  std::atomic<bool> done{false};
  std::atomic<int> answered{0}, wrong{0};
  std::thread lone([&] {
    try {
      SocketClient c("127.0.0.1", port_);
      for (int round = 0; round < 1000 && !done.load(); ++round) {
        const int n = call_back_to_back(c, "l" + std::to_string(round) + "-", 5ms);
        answered += n;
        if (n == 0) ++wrong;
      }
    } catch (const std::exception&) {
      ++wrong;
    }
  });
  std::this_thread::sleep_for(20ms);  // the lone client's socket is read directly by now
  auto other = connect();
  other->send_line("h worker hold (1,)");
  EXPECT_EQ(roundtrip(*other, "p test ping"), "p SUCCESS \"pong\"");
  other->send_line("r worker release (5,)");
  EXPECT_EQ(next_lines(*other, 2), (std::multiset<std::string>{"r SUCCESS true", "h SUCCESS 5"}));
  auto late = connect();  // a new connection is accepted meanwhile
  EXPECT_EQ(roundtrip(*late, "q test_component add (3, 4)"), "q SUCCESS 7");
  done = true;
  lone.join();
  EXPECT_GT(answered.load(), 0);
  EXPECT_EQ(wrong.load(), 0);
}

TEST_F(SocketTransport, AClientFloodingBlankLinesDoesNotHoldUpTheOthers) {
  // the flooder is read directly (it sends alone, then always has bytes waiting); the
  // probe's request must be answered while the flood goes on, not after it (issue #35,
  // item 3: before, the event loop was polled only when a direct read found nothing)
  std::atomic<bool> answered{false}, flood_over{false};
  std::thread flooder([&] {
    try {
      SocketClient c("127.0.0.1", port_);
      const std::string blanks(64 * 1024, '\n');
      const auto until = std::chrono::steady_clock::now() + 5s;
      while (!answered.load() && std::chrono::steady_clock::now() < until) c.send_raw(blanks);
    } catch (const std::exception&) {}
    flood_over = true;
  });
  std::this_thread::sleep_for(50ms);  // the flooder is read directly by now
  auto probe = connect();
  EXPECT_EQ(roundtrip(*probe, "p test ping"), "p SUCCESS \"pong\"");
  EXPECT_FALSE(flood_over.load()) << "the probe was answered only once the flood had stopped";
  answered = true;
  flooder.join();
}

TEST_F(SocketTransport, RepliesFromTheSimulationThreadReachALoneClientReadDirectly) {
  // the simulation lock is held: the request read directly is queued, run by the
  // process() thread, and its reply handed over to the polling I/O thread
  auto c = connect();
  EXPECT_GT(call_back_to_back(*c, "a-", 20ms), 0);
  {
    std::lock_guard stepping(*manager_->gate());
    c->send_line("s1 test_component add (1, 2)");
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_EQ(next_line(*c), "s1 SUCCESS 3");
  EXPECT_GT(call_back_to_back(*c, "b-", 20ms), 0);
}

// ---- async services, cancel, policies

TEST_F(SocketTransport, AsyncResultIsPushedWhenItCompletes) {
  auto c = connect();
  c->send_line("req2 worker hold (5,)");
  // other replies flow while it runs
  EXPECT_EQ(roundtrip(*c, "q1 test_component add (1,2)"), "q1 SUCCESS 3");
  EXPECT_EQ(roundtrip(*c, "q2 test ping"), "q2 SUCCESS \"pong\"");
  c->send_line("q3 worker release ('done!',)");
  EXPECT_EQ(next_lines(*c, 2),
            (std::multiset<std::string>{"q3 SUCCESS true", "req2 SUCCESS \"done!\""}));
}

TEST_F(SocketTransport, AsyncResultGoesToTheConnectionThatAsked) {
  auto asker = connect();
  auto other = connect();
  asker->send_line("a1 worker hold (1,)");
  // the other connection completes it
  EXPECT_EQ(roundtrip(*asker, "sync test ping"), "sync SUCCESS \"pong\"");  // a1 has started
  EXPECT_EQ(roundtrip(*other, "r1 worker release (7,)"), "r1 SUCCESS true");
  EXPECT_EQ(next_line(*asker), "a1 SUCCESS 7");
  EXPECT_EQ(roundtrip(*other, "r2 test ping"), "r2 SUCCESS \"pong\"");  // nothing else arrived
}

TEST_F(SocketTransport, CancelEndsPreemptedAndGetsNoReplyOfItsOwn) {
  auto c = connect();
  c->send_line("c1 worker hold (1,)");
  c->send_line("c1 cancel");
  EXPECT_EQ(next_line(*c), "c1 PREEMPTED");
  EXPECT_EQ(roundtrip(*c, "c2 test ping"), "c2 SUCCESS \"pong\"");
  // the component is free again
  c->send_line("c3 worker hold (2,)");
  c->send_line("c4 worker release (0,)");
  EXPECT_EQ(next_lines(*c, 2), (std::multiset<std::string>{"c4 SUCCESS true", "c3 SUCCESS 0"}));
}

TEST_F(SocketTransport, CancelAfterManyAnsweredRequestsOfTheSameReadFindsItsRequest) {
  // A cancel first runs the calls its read gathered before it (its request may be among
  // them); answering them removes their ids from the connection's table, which may move
  // the entry of the request the cancel names: the cancel still ends that request.
  auto c = connect();
  constexpr int k_rounds = 20, k_calls = 64;
  for (int round = 0; round < k_rounds; ++round) {
    const std::string hold = "h" + std::to_string(round);
    std::string burst = hold + " worker hold (1,)\n";
    std::multiset<std::string> expected{hold + " PREEMPTED"};
    for (int i = 0; i < k_calls; ++i) {
      const std::string id = "s" + std::to_string(round) + "_" + std::to_string(i);
      burst += id + " test ping\n";
      expected.insert(id + " SUCCESS \"pong\"");
    }
    c->send_raw(burst + hold + " cancel\n");
    ASSERT_EQ(next_lines(*c, k_calls + 1), expected) << "round " << round;
  }
  EXPECT_EQ(roundtrip(*c, "end test ping"), "end SUCCESS \"pong\"");
}

TEST_F(SocketTransport, CancelOfUnknownOrFinishedIdIsIgnored) {
  auto c = connect();
  c->send_line("nobody cancel");
  EXPECT_EQ(roundtrip(*c, "z1 test_component add (1,2)"), "z1 SUCCESS 3");
  c->send_line("z1 cancel");  // already answered
  EXPECT_EQ(roundtrip(*c, "z2 test ping"), "z2 SUCCESS \"pong\"");
}

TEST_F(SocketTransport, CancelIsScopedToTheConnection) {
  auto owner = connect();
  auto stranger = connect();
  owner->send_line("x worker hold (1,)");
  EXPECT_EQ(roundtrip(*owner, "sync test ping"), "sync SUCCESS \"pong\"");
  stranger->send_line("x cancel");  // same id, other connection: not its request
  EXPECT_EQ(roundtrip(*stranger, "s1 test ping"), "s1 SUCCESS \"pong\"");
  EXPECT_EQ(roundtrip(*stranger, "s2 worker release ('still running',)"), "s2 SUCCESS true");
  EXPECT_EQ(next_line(*owner), "x SUCCESS \"still running\"");
}

TEST_F(SocketTransport, SameIdOnTwoConnectionsIsFine) {
  auto a = connect();
  auto b = connect();
  a->send_line("same worker hold (1,)");
  EXPECT_EQ(roundtrip(*a, "sync test ping"), "sync SUCCESS \"pong\"");
  EXPECT_EQ(roundtrip(*b, "same test_component add (1,2)"), "same SUCCESS 3");
  EXPECT_EQ(roundtrip(*b, "r worker release (1,)"), "r SUCCESS true");
  EXPECT_EQ(next_line(*a), "same SUCCESS 1");
}

TEST_F(SocketTransport, SecondPendingRequestWithSameIdIsRefused) {
  auto c = connect();
  c->send_line("d1 worker hold (1,)");
  EXPECT_EQ(
      roundtrip(*c, "d1 test_component add (1,2)"),
      "d1 FAILED \"Request id 'd1' is already pending on this connection: wait for its reply or "
      "use another id\"");
  c->send_line("d2 worker release (1,)");
  EXPECT_EQ(next_lines(*c, 2), (std::multiset<std::string>{"d2 SUCCESS true", "d1 SUCCESS 1"}));
  EXPECT_EQ(roundtrip(*c, "d1 test_component add (1,2)"), "d1 SUCCESS 3");  // free again
}

TEST_F(SocketTransport, InterruptibleServiceIsPreemptedByTheNextRequest) {
  auto c = connect();
  c->send_line("c3 worker hold (20,)");
  c->send_line("c4 worker hold (2,)");
  EXPECT_EQ(next_line(*c), "c3 PREEMPTED");
  c->send_line("r worker release ('done!',)");
  EXPECT_EQ(next_lines(*c, 2),
            (std::multiset<std::string>{"r SUCCESS true", "c4 SUCCESS \"done!\""}));
}

TEST_F(SocketTransport, NonInterruptibleServiceRefusesTheNextRequest) {
  auto c = connect();
  c->send_line("c5 strict hold (20,)");
  EXPECT_EQ(roundtrip(*c, "c6 strict hold (2,)"),
            "c6 FAILED \"A non-interruptible service (strict.hold) is already running\"");
  c->send_line("r strict release ('done!',)");
  EXPECT_EQ(next_lines(*c, 2),
            (std::multiset<std::string>{"r SUCCESS true", "c5 SUCCESS \"done!\""}));
}

TEST_F(SocketTransport, NoLocalPolicyFollowsTheGlobalRejectPolicy) {
  auto c = connect();
  c->send_line("c7 plain hold (20,)");
  EXPECT_EQ(roundtrip(*c, "c8 plain hold (2,)"),
            "c8 FAILED \"A service (plain.hold) is already running. I do not know what to do.\"");
  c->send_line("r plain release (1,)");
  EXPECT_EQ(next_lines(*c, 2), (std::multiset<std::string>{"r SUCCESS true", "c7 SUCCESS 1"}));
}

// ---- clients that vanish, flood or stop reading

TEST_F(SocketTransport, ManyClientsAtOnce) {
  constexpr int k_clients = 8, k_requests = 25;
  std::vector<std::thread> threads;
  std::atomic<int> ok{0};
  for (int t = 0; t < k_clients; ++t) {
    threads.emplace_back([&, t] {
      try {
        SocketClient c("127.0.0.1", port_);
        for (int i = 0; i < k_requests; ++i) {
          std::string id = "c" + std::to_string(t) + "-" + std::to_string(i);
          c.send_line(id + " test_component add (" + std::to_string(t) + "," + std::to_string(i) +
                      ")");
          auto line = c.read_line(10s);
          if (line && *line == id + " SUCCESS " + std::to_string(t + i)) ++ok;
        }
      } catch (const std::exception&) {}
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(ok.load(), k_clients * k_requests);
}

TEST_F(SocketTransport, PipelinedRequestsAreAllAnswered) {
  auto c = connect();
  std::string batch;
  constexpr int k_count = 500;
  for (int i = 0; i < k_count; ++i)
    batch += std::to_string(i) + " test_component add (" + std::to_string(i) + ",1)\n";
  c->send_raw(batch);
  for (int i = 0; i < k_count; ++i)
    ASSERT_EQ(next_line(*c), std::to_string(i) + " SUCCESS " + std::to_string(i + 1));
}

}  // namespace
}  // namespace simgate::socket::test
