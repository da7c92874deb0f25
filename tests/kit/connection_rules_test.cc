// simgate/kit/connection_rules.h: the per-peer count and the choice of the connection that
// makes room at max_connections (shared by the line transports and the websocket transport).
#include "simgate/kit/connection_rules.h"

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace simgate::kit {
namespace {

using boost::asio::ip::make_address;

TEST(PeerCountsTest, RefusesAnAddressAtItsLimitAndNeverLoopback) {
  PeerCounts counts(2);
  const auto remote = make_address("192.0.2.7"), other = make_address("198.51.100.1");
  counts.add(remote);
  EXPECT_EQ(counts.refusal_reason(remote), "");
  counts.add(remote);
  EXPECT_EQ(counts.refusal_reason(remote),
            "too many connections from 192.0.2.7 (max_connections_per_peer 2)");
  EXPECT_EQ(counts.refusal_reason(other), "");  // another address has its own budget
  counts.remove(remote);
  EXPECT_EQ(counts.refusal_reason(remote), "");
  for (const char* loopback : {"127.0.0.1", "127.0.0.2", "::1", "::ffff:127.0.0.1"}) {
    const auto address = make_address(loopback);
    for (int i = 0; i < 5; ++i) counts.add(address);
    EXPECT_EQ(counts.refusal_reason(address), "") << loopback;
    EXPECT_EQ(counts.count(address), 0u) << loopback;
  }
}

TEST(PeerCountsTest, ZeroMeansNoLimit) {
  PeerCounts counts(0);
  const auto remote = make_address("192.0.2.7");
  for (int i = 0; i < 100; ++i) counts.add(remote);
  EXPECT_EQ(counts.refusal_reason(remote), "");
}

struct TimedConnection {
  std::uint32_t idle = 0, silent = 0;
  std::size_t owed = 0;
  std::string name;
  std::string closed_for;
  std::uint32_t idle_ticks() const { return idle; }
  std::uint32_t silent_ticks() const { return silent; }
  std::size_t unanswered() const { return owed; }
  const std::string& label() const { return name; }
  void end(std::string_view reason, Ending how) {
    closed_for = reason;
    EXPECT_EQ(how, Ending::refused);
  }
};

TEST(MakeRoomTest, ClosesTheConnectionIdleLongestOnceIdleLongEnough) {
  std::vector<std::shared_ptr<TimedConnection>> all = {
      std::make_shared<TimedConnection>(TimedConnection{3, 3, 0, "a", ""}),
      std::make_shared<TimedConnection>(TimedConnection{7, 7, 0, "b", ""}),
      std::make_shared<TimedConnection>(TimedConnection{0, 9, 1, "c", ""})};
  EXPECT_FALSE(make_room(all, 10, "test", 3));  // none idle (or silent) for 10 sweeps
  EXPECT_TRUE(make_room(all, 5, "test", 3));
  EXPECT_EQ(all[1]->closed_for, "idle while the server was full");
  EXPECT_EQ(all[0]->closed_for, "");
  EXPECT_EQ(all[2]->closed_for, "");
}

TEST(MakeRoomTest, FailingAnIdleOneTheOneSilentLongestWhileItWaits) {
  std::vector<std::shared_ptr<TimedConnection>> all = {
      std::make_shared<TimedConnection>(TimedConnection{0, 2, 1, "a", ""}),
      std::make_shared<TimedConnection>(TimedConnection{0, 8, 1, "b", ""})};
  EXPECT_TRUE(make_room(all, 4, "test", 2));
  EXPECT_EQ(all[1]->closed_for, "silent while the server was full");
  EXPECT_EQ(sweep_ticks(std::chrono::milliseconds(1)), 1u);
  EXPECT_EQ(sweep_ticks(std::chrono::milliseconds(1000)), 4u);
}

}  // namespace
}  // namespace simgate::kit
