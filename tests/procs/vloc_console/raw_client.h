#pragma once
// A minimal HTTP and WebSocket client on raw TCP sockets, for the console's
// process tests: it sends exactly the bytes a test asks for (a browser would
// normalise "../" away; an attacker does not), with timeouts on every read.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <optional>
#include <random>
#include <string>

namespace vloc::testing {

class RawClient {
 public:
  explicit RawClient(int port) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0) Close();
  }
  ~RawClient() { Close(); }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;

  bool ok() const { return fd_ >= 0; }
  void Close() {
    if (fd_ >= 0) close(fd_);
    fd_ = -1;
  }
  // A small receive buffer makes a client slow to drain (slow-client test).
  void SetReceiveBuffer(int bytes) { setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &bytes, sizeof(bytes)); }

  bool Send(const std::string& bytes) {
    size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<size_t>(n);
    }
    return true;
  }

  // Reads until the peer closes or timeout_s passes; returns what came.
  std::string ReadAll(double timeout_s) {
    std::string out;
    while (ReadSome(&out, timeout_s)) {
    }
    return out;
  }

  // One HTTP/1.0 GET of exactly `target`; the whole response (headers + body).
  static std::string Get(int port, const std::string& target, double timeout_s = 5,
                         const std::string& host = "127.0.0.1") {
    RawClient c(port);
    if (!c.Send("GET " + target + " HTTP/1.0\r\nHost: " + host + "\r\n\r\n")) return "";
    return c.ReadAll(timeout_s);
  }
  static int StatusOf(const std::string& response) {
    if (response.compare(0, 5, "HTTP/") != 0 || response.size() < 12) return -1;
    return std::atoi(response.c_str() + 9);
  }

  // The WebSocket opening handshake on `path` with this Host and extra
  // header lines (each ending in \r\n, e.g. an Origin); true when the
  // server agreed. The server's answer stays in handshake().
  bool Upgrade(const std::string& path = "/ws", const std::string& host = "127.0.0.1",
               const std::string& extra_headers = "") {
    if (!Send("GET " + path + " HTTP/1.1\r\nHost: " + host +
              "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
              "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n" +
              extra_headers + "\r\n"))
      return false;
    while (buffer_.find("\r\n\r\n") == std::string::npos)
      if (!ReadSome(&buffer_, 5)) return false;
    handshake_ = buffer_.substr(0, buffer_.find("\r\n\r\n"));
    const bool ok = buffer_.compare(0, 12, "HTTP/1.1 101") == 0;
    buffer_.erase(0, buffer_.find("\r\n\r\n") + 4);
    return ok;
  }
  const std::string& handshake() const { return handshake_; }

  // A masked client frame (opcode 1 = text) with `payload`.
  static std::string Frame(const std::string& payload, int opcode = 1) {
    std::string f(1, static_cast<char>(0x80 | opcode));
    const size_t n = payload.size();
    if (n < 126) {
      f += static_cast<char>(0x80 | n);
    } else if (n < 65536) {
      f += static_cast<char>(0x80 | 126);
      f += static_cast<char>(n >> 8), f += static_cast<char>(n & 0xff);
    } else {
      f += static_cast<char>(0x80 | 127);
      for (int i = 7; i >= 0; --i) f += static_cast<char>((static_cast<uint64_t>(n) >> (8 * i)) & 0xff);
    }
    const char mask[4] = {0x12, 0x34, 0x56, 0x78};
    f.append(mask, 4);
    for (size_t i = 0; i < n; ++i) f += static_cast<char>(payload[i] ^ mask[i % 4]);
    return f;
  }
  bool SendText(const std::string& text) { return Send(Frame(text)); }

  // The next text message from the server, or nullopt on timeout / close.
  std::optional<std::string> NextText(double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (true) {
      size_t header = 0;
      uint64_t length = 0;
      if (ParseHeader(&header, &length) && buffer_.size() >= header + length) {
        const int opcode = buffer_[0] & 0x0f;
        std::string payload = buffer_.substr(header, length);
        buffer_.erase(0, header + length);
        if (opcode == 1) return payload;
        if (opcode == 8) return std::nullopt;
        continue;
      }
      const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0 || !ReadSome(&buffer_, left)) return std::nullopt;
    }
  }
  // The next text message containing `needle`.
  std::optional<std::string> WaitFor(const std::string& needle, double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (true) {
      const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0) return std::nullopt;
      auto m = NextText(left);
      if (!m) return std::nullopt;
      if (m->find(needle) != std::string::npos) return m;
    }
  }

 private:
  bool ParseHeader(size_t* header, uint64_t* length) const {
    if (buffer_.size() < 2) return false;
    const uint64_t n = static_cast<uint8_t>(buffer_[1]) & 0x7f;
    if (n < 126) return (*header = 2, *length = n, true);
    const size_t ext = n == 126 ? 2 : 8;
    if (buffer_.size() < 2 + ext) return false;
    uint64_t v = 0;
    for (size_t i = 0; i < ext; ++i) v = (v << 8) | static_cast<uint8_t>(buffer_[2 + i]);
    *header = 2 + ext;
    *length = v;
    return true;
  }
  bool ReadSome(std::string* out, double timeout_s) {
    if (fd_ < 0) return false;
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(timeout_s * 1000)) <= 0) return false;
    char buf[65536];
    const ssize_t n = recv(fd_, buf, sizeof(buf), 0);
    if (n <= 0) return false;
    out->append(buf, static_cast<size_t>(n));
    return true;
  }

  int fd_ = -1;
  std::string buffer_, handshake_;
};

}  // namespace vloc::testing
