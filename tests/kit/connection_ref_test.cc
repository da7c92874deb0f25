// kit::ConnectionRef (kit/connection.h): where a reply goes, without sharing the connection's
// ownership. A ref finds its connection while it is open and nothing once its server was told
// it closed, even when a later connection takes the same slot of the server's table (and,
// with the allocator's help, maybe the same address). Real sockets on 127.0.0.1; the test
// thread plays the I/O thread (the event loop never runs: nothing is read).
#include <memory>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "simgate/kit/connection.h"

namespace simgate::kit {
namespace {

namespace asio = boost::asio;
using asio::ip::tcp;

// A protocol's part of a connection, another base of its class (as jsonrpc::Session is).
struct Part {
  int value = 0;
};

class TestConnection : public Connection, public Part {
 public:
  using Connection::Connection;
  void start() override {}  // never reads: the test only opens and closes

 protected:
  void consume(std::string_view) override {}
  void input_ended() override {}
  bool message_unfinished() const override { return false; }
};

class TestServer : public ConnectionServer {
 public:
  TestServer() : ConnectionServer("test server", TcpOptions{}) {}
  void on_messages_done(Connection&, bool) override {}
  void on_closed(Connection&) override { ++closed; }
  int closed = 0;
};

class ConnectionRefTest : public ::testing::Test {
 protected:
  ConnectionRefTest() : acceptor_(io_, tcp::endpoint(asio::ip::address_v4::loopback(), 0)) {}
  ~ConnectionRefTest() override { server_.close_all(); }

  // A connection of the server (its client's socket kept in clients_), added and started.
  std::shared_ptr<TestConnection> open() {
    clients_.emplace_back(io_);
    clients_.back().connect(acceptor_.local_endpoint());
    auto c = std::make_shared<TestConnection>(acceptor_.accept(), server_, ConnectionLimits{},
                                              "test server", ++number_);
    server_.add(c);
    return c;
  }

  asio::io_context io_;
  tcp::acceptor acceptor_;
  std::vector<tcp::socket> clients_;
  TestServer server_;
  std::uint64_t number_ = 0;
};

TEST_F(ConnectionRefTest, FindsItsConnectionWhileOpenAndNothingOnceClosed) {
  auto c = open();
  c->value = 7;
  const ConnectionRef<Part> part(*c, *c);
  const ConnectionRef<Connection> whole = c->ref();
  ASSERT_EQ(part.get(), static_cast<Part*>(c.get()));
  EXPECT_EQ(part.get()->value, 7);
  EXPECT_EQ(whole.get(), c.get());
  // copies are plain copies: each finds the same connection
  const ConnectionRef<Part> copy = part;
  EXPECT_EQ(copy.get(), part.get());

  c->close("test");
  EXPECT_EQ(server_.closed, 1);
  EXPECT_EQ(part.get(), nullptr);  // the object still lives (c): the ref says closed anyway
  EXPECT_EQ(copy.get(), nullptr);
  EXPECT_EQ(whole.get(), nullptr);
}

TEST_F(ConnectionRefTest, ARefMadeByDefaultOrBeforeAddFindsNothing) {
  EXPECT_EQ(ConnectionRef<Part>().get(), nullptr);
  tcp::socket client(io_);
  client.connect(acceptor_.local_endpoint());
  TestConnection unadded(acceptor_.accept(), server_, ConnectionLimits{}, "test server", 99);
  EXPECT_EQ(unadded.ref().get(), nullptr);
}

TEST_F(ConnectionRefTest, ALaterConnectionInTheSameSlotIsNotFoundByAnOldRef) {
  auto first = open();
  const ConnectionRef<Part> old(*first, *first);
  first->close("left");
  first.reset();  // freed: the next connection may even get its address
  // the server's table reuses the freed slot first; the old ref names its previous
  // generation and finds nothing, over many reuses
  for (int i = 0; i < 100; ++i) {
    auto next = open();
    const ConnectionRef<Part> current(*next, *next);
    EXPECT_EQ(current.get(), static_cast<Part*>(next.get()));
    EXPECT_EQ(old.get(), nullptr) << "reuse " << i;
    next->close("left");
    EXPECT_EQ(current.get(), nullptr);
  }
}

TEST_F(ConnectionRefTest, CloseAllLeavesNoRefFindingAnything) {
  auto a = open();
  auto b = open();
  const ConnectionRef<Part> ra(*a, *a), rb(*b, *b);
  EXPECT_NE(ra.get(), nullptr);
  EXPECT_NE(rb.get(), nullptr);
  server_.close_all();
  EXPECT_EQ(ra.get(), nullptr);
  EXPECT_EQ(rb.get(), nullptr);
  EXPECT_EQ(server_.closed, 2);
}

}  // namespace
}  // namespace simgate::kit
