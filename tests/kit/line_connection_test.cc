// kit/src/line_connection.cc's pure parts: which lines are HTTP request lines, so that a line
// connection closes on one (the transports' own tests send a browser's POST over TCP:
// tests/socket/tcp_transport_test.cc, TcpTransportCrossSite).
#include <gtest/gtest.h>

#include "simgate/kit/line_connection.h"

namespace simgate::kit {
namespace {

TEST(HttpRequestLine, WhatBrowsersAndHttpClientsSendFirstIsOne) {
  for (const char* line : {"POST / HTTP/1.1", "POST / HTTP/1.1\r", "GET /index.html?x=1 HTTP/1.0\r",
                           "OPTIONS * HTTP/1.1", "PRI * HTTP/2.0",
                           "CONNECT 127.0.0.1:4000 HTTP/1.1", "DELETE /robots/1 HTTP/1.1"})
    EXPECT_TRUE(is_http_request_line(line)) << line;
}

TEST(HttpRequestLine, NoLineOfTheLineProtocolsIsOne) {
  for (const char* line :
       {"1 simulation quit", "id1 robot.motion set_speed [0.5, 0.2]", "p test ping HTTP/1.1",
        R"({"jsonrpc":"2.0","method":"simulation.quit","id":1})", R"({"v": 0.5, "w": "HTTP/1.1"})",
        "", "\r", "GET", "GET /", "GET / HTTP/1.1 extra", "GET  HTTP/1.1", "GET / HTTP/11",
        "GET / HTTP/1.x", "get / HTTP/1.1", "Host: 127.0.0.1:4000", "GET / / HTTP/1.1",
        "AVERYLONGMETHODNAMEX / HTTP/1.1"})
    EXPECT_FALSE(is_http_request_line(line)) << line;
}

}  // namespace
}  // namespace simgate::kit
