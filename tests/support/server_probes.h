#pragma once
// What the server's hardening tests probe it with: one raw HTTP exchange
// (sent in pieces, with pauses), the port of a test server's URL, and the text
// of a shipped settings file.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

#include "core/common/data_paths.h"

namespace orbatlas::test {

// One raw HTTP exchange on a fresh connection: sends `request`, returns what
// came back until the server closed or `wait` passed (status line first).
// Sends `request` in `pieces` equal parts, `pause` apart, then reads the reply
// (until its JSON body has come, or `wait` without a byte).
inline std::string raw_exchange(int port, const std::string& request, std::chrono::milliseconds wait, int pieces = 1,
                                std::chrono::milliseconds pause = std::chrono::milliseconds(0)) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return "connect failed";
  }
  const std::size_t part = (request.size() + static_cast<std::size_t>(pieces) - 1) / static_cast<std::size_t>(pieces);
  for (std::size_t sent = 0; sent < request.size(); sent += part) {
    if (sent > 0) std::this_thread::sleep_for(pause);
    const std::size_t n = std::min(part, request.size() - sent);
    for (std::size_t done = 0; done < n;) {
      const ssize_t k = ::send(fd, request.data() + sent + done, n - done, MSG_NOSIGNAL);
      if (k <= 0) break;
      done += static_cast<std::size_t>(k);
    }
  }
  timeval tv{static_cast<time_t>(wait.count() / 1000), static_cast<suseconds_t>((wait.count() % 1000) * 1000)};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string reply;
  char chunk[4096];
  for (ssize_t n; (n = ::recv(fd, chunk, sizeof chunk, 0)) > 0;) {
    reply.append(chunk, static_cast<std::size_t>(n));
    if (reply.find("\r\n\r\n") != std::string::npos && reply.find("}") != std::string::npos) break;
  }
  ::close(fd);
  return reply;
}

inline int port_of(const std::string& url) { return std::stoi(url.substr(url.rfind(':') + 1)); }

inline std::string settings_text(const std::string& config) {
  std::ifstream in(shipped_config_dir() / (config + ".yaml"));
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace orbatlas::test
