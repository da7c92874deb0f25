// bench/ws_client.h — the benchmarks' WebSocket client: a few lines of RFC 6455 over a plain
// socket (the upgrade, masked text frames out, unmasked frames in), read by a thread that
// polls many of them, as a browser page or a Foxglove app reads its connection: not Beast, so
// that the server's side alone is measured. Used by web_bench.cc and foxglove_bench.cc.
#ifndef SIMGATE_BENCH_WS_CLIENT_H_
#define SIMGATE_BENCH_WS_CLIENT_H_

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include "bench_util.h"

namespace simgate::bench {

// One WebSocket client connection: the upgrade, masked text messages out, whole messages in.
class WebSocketClient {
 public:
  // Connects to 127.0.0.1:`port` and upgrades, offering `subprotocol` (when not empty).
  explicit WebSocketClient(std::uint16_t port, std::string_view subprotocol = "")
      : fd_(connect_loopback(port)) {
    std::string request =
        "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n";
    if (!subprotocol.empty())
      request += "Sec-WebSocket-Protocol: " + std::string(subprotocol) + "\r\n";
    send_all(request + "\r\n");
    const auto deadline = Clock::now() + std::chrono::seconds(30);
    std::size_t end;
    while ((end = buffer_.find("\r\n\r\n")) == std::string::npos) {
      if (Clock::now() >= deadline || !read_some(100))
        throw std::runtime_error("no WebSocket handshake answer");
    }
    if (!buffer_.starts_with("HTTP/1.1 101"))
      throw std::runtime_error("the WebSocket upgrade was refused: " +
                               buffer_.substr(0, buffer_.find('\r')));
    buffer_.erase(0, end + 4);
  }
  ~WebSocketClient() { ::close(fd_); }
  WebSocketClient(const WebSocketClient&) = delete;
  WebSocketClient& operator=(const WebSocketClient&) = delete;

  int fd() const { return fd_; }

  // One text message, in one masked frame (a client's frames are masked, RFC 6455 5.3).
  void send_text(std::string_view text) {
    static constexpr std::array<unsigned char, 4> k_mask = {0x5a, 0x17, 0xc3, 0x9e};
    std::string frame(1, static_cast<char>(0x81));  // FIN, text
    const std::size_t n = text.size();
    if (n < 126) {
      frame += static_cast<char>(0x80 | n);
    } else if (n < 65536) {
      frame += static_cast<char>(0x80 | 126);
      frame += static_cast<char>(n >> 8), frame += static_cast<char>(n & 0xff);
    } else {
      frame += static_cast<char>(0x80 | 127);
      for (int shift = 56; shift >= 0; shift -= 8) frame += static_cast<char>((n >> shift) & 0xff);
    }
    frame.append(reinterpret_cast<const char*>(k_mask.data()), k_mask.size());
    for (std::size_t i = 0; i < n; ++i) frame += static_cast<char>(text[i] ^ k_mask[i % 4]);
    send_all(frame);
  }

  // Reads what the socket holds (it is readable) and hands each whole data message (the server
  // sends them unfragmented) to `on_message(bool binary, std::string_view payload)`.
  template <class F>
  void read_messages(F&& on_message) {
    if (!read_some(0)) throw std::runtime_error("the WebSocket connection closed");
    std::size_t at = 0;
    for (;;) {
      if (buffer_.size() - at < 2) break;
      const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(buffer_[at + i]); };
      const unsigned opcode = byte(0) & 0x0f;
      std::uint64_t length = byte(1) & 0x7f;
      std::size_t header = 2;
      if (length == 126) {
        if (buffer_.size() - at < 4) break;
        length = (static_cast<std::uint64_t>(byte(2)) << 8) | byte(3);
        header = 4;
      } else if (length == 127) {
        if (buffer_.size() - at < 10) break;
        length = 0;
        for (int i = 2; i < 10; ++i) length = (length << 8) | byte(i);
        header = 10;
      }
      if (buffer_.size() - at < header + length) break;
      const std::string_view payload(buffer_.data() + at + header, length);
      if (opcode == 0x8) throw std::runtime_error("the server closed the WebSocket");
      if (opcode == 0x1 || opcode == 0x2) on_message(opcode == 0x2, payload);
      at += header + length;  // pings are not answered: runs are short
    }
    buffer_.erase(0, at);
  }

 private:
  void send_all(std::string_view bytes) {
    while (!bytes.empty()) {
      const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
      if (n <= 0) throw std::runtime_error("send failed on a WebSocket connection");
      bytes.remove_prefix(static_cast<std::size_t>(n));
    }
  }
  // Appends what arrives within `timeout_ms`; false when the peer closed.
  bool read_some(int timeout_ms) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return true;
    char chunk[65536];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n <= 0) return false;
    buffer_.append(chunk, static_cast<std::size_t>(n));
    return true;
  }

  int fd_;
  std::string buffer_;  // received, not yet handed out
};

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_WS_CLIENT_H_
