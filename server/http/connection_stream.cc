#include "server/http/connection_stream.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <fcntl.h>
#include <openssl/ssl.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>

#include <nlohmann/json.hpp>

namespace orbatlas {
namespace {

using Clock = ConnectionStream::Clock;

void address_of(socket_t sock, bool peer, std::string& ip, int& port) {
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  const int r = peer ? ::getpeername(sock, reinterpret_cast<sockaddr*>(&addr), &len)
                     : ::getsockname(sock, reinterpret_cast<sockaddr*>(&addr), &len);
  if (r != 0) return;
  char text[INET6_ADDRSTRLEN] = {};
  if (addr.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&addr);
    ::inet_ntop(AF_INET, &a->sin_addr, text, sizeof text);
    port = ntohs(a->sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&addr);
    ::inet_ntop(AF_INET6, &a->sin6_addr, text, sizeof text);
    port = ntohs(a->sin6_port);
  }
  ip = text;
}

bool starts_with_nocase(std::string_view text, std::string_view prefix) {
  if (text.size() < prefix.size()) return false;
  for (std::size_t i = 0; i < prefix.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(text[i])) != std::tolower(static_cast<unsigned char>(prefix[i])))
      return false;
  return true;
}

// The status of a reply head ("HTTP/1.1 404 Not Found\r\n..."), 0 if none.
int status_of(std::string_view head) {
  if (head.size() < 12 || head.substr(0, 5) != "HTTP/") return 0;
  const std::size_t space = head.find(' ');
  if (space == std::string_view::npos || space + 4 > head.size()) return 0;
  int status = 0;
  for (std::size_t i = space + 1; i < space + 4; ++i) {
    if (!std::isdigit(static_cast<unsigned char>(head[i]))) return 0;
    status = status * 10 + (head[i] - '0');
  }
  return status;
}

// Whether a reply head has the line `Connection: close`.
bool says_close(std::string_view head) {
  for (std::size_t at = head.find("\r\n"); at != std::string_view::npos; at = head.find("\r\n", at + 2)) {
    const std::string_view line = head.substr(at + 2, head.find("\r\n", at + 2) - (at + 2));
    if (!starts_with_nocase(line, "connection:")) continue;
    std::string value(line.substr(11));
    value.erase(0, value.find_first_not_of(" \t"));
    if (starts_with_nocase(value, "close")) return true;
  }
  return false;
}

}  // namespace

bool poll_for(socket_t sock, short events, std::chrono::steady_clock::duration timeout) {
  if (timeout <= Clock::duration::zero()) return false;
  pollfd p{sock, events, 0};
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count();
  int r = 0;
  do {
    r = ::poll(&p, 1, static_cast<int>(std::max<long long>(1, std::min<long long>(ms, 1 << 30))));
  } while (r < 0 && errno == EINTR);
  return r > 0;
}

ConnectionStream::ConnectionStream(socket_t sock, Options options)
    : sock_(sock), options_(std::move(options)), buffer_(new char[kReadBuffer]) {}

ConnectionStream::~ConnectionStream() {
  if (ssl_) SSL_free(ssl_);
}

bool ConnectionStream::handshake(Clock::time_point deadline) {
  if (!options_.tls) return true;
  // Non-blocking from here: every wait is a poll with a deadline.
  const int flags = ::fcntl(sock_, F_GETFL, 0);
  if (flags < 0 || ::fcntl(sock_, F_SETFL, flags | O_NONBLOCK) != 0) return false;
  ssl_ = SSL_new(options_.tls);
  if (!ssl_ || SSL_set_fd(ssl_, sock_) != 1) return false;
  for (;;) {
    const int r = SSL_accept(ssl_);
    if (r == 1) return true;
    const int error = SSL_get_error(ssl_, r);
    const short events = error == SSL_ERROR_WANT_READ ? POLLIN : error == SSL_ERROR_WANT_WRITE ? POLLOUT : 0;
    if (events == 0 || !poll_for(sock_, events, deadline - Clock::now())) {
      dropped_ = true;
      return false;
    }
  }
}

void ConnectionStream::close_notify() {
  if (ssl_ && !dropped_) SSL_shutdown(ssl_);  // non-blocking: sent if it fits, never waited for
}

bool ConnectionStream::has_buffered() const { return begin_ < end_ || (ssl_ && SSL_pending(ssl_) > 0); }

void ConnectionStream::start_request(Clock::time_point deadline) {
  phase_ = Phase::kHead;
  deadline_ = deadline;
  head_read_ = 0;
  expected_body_.reset();
  body_read_ = 0;
  reply_started_ = false;
  must_close_ = false;
  answered_status_ = 0;
}

void ConnectionStream::headers_received(std::optional<std::uint64_t> body_bytes,
                                        std::optional<Clock::time_point> deadline) {
  phase_ = Phase::kBody;
  expected_body_ = body_bytes;
  body_read_ = 0;
  deadline_ = deadline;
}

bool ConnectionStream::wait_readable(Clock::duration wait) const {
  if (deadline_) wait = std::min(wait, *deadline_ - Clock::now());
  return poll_for(sock_, POLLIN, wait);
}

bool ConnectionStream::is_readable() const { return has_buffered() || wait_readable(options_.read_timeout); }

bool ConnectionStream::is_writable() const { return poll_for(sock_, POLLOUT, options_.write_timeout); }

ssize_t ConnectionStream::receive_now() {
  if (!ssl_) {
    ssize_t n = 0;
    do {
      n = ::recv(sock_, buffer_.get(), kReadBuffer, MSG_DONTWAIT);
    } while (n < 0 && errno == EINTR);
    return n;
  }
  const int n = SSL_read(ssl_, buffer_.get(), static_cast<int>(kReadBuffer));
  if (n > 0) return n;
  const int error = SSL_get_error(ssl_, n);
  if (error == SSL_ERROR_ZERO_RETURN) return 0;
  // A record not whole yet; a renegotiation's write is not ours to wait for here.
  errno = error == SSL_ERROR_WANT_READ || error == SSL_ERROR_WANT_WRITE ? EAGAIN : ECONNRESET;
  return -1;
}

ssize_t ConnectionStream::read(char* ptr, size_t size) {
  if (dropped_) return -1;
  if (begin_ == end_) {
    // What is there already, without a wait; else wait (bounded) and read.
    ssize_t n = receive_now();
    while (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      const bool body = phase_ == Phase::kBody && options_.on_body_wait;
      if (body && !options_.on_body_wait(true)) return -1;  // closed for room
      const bool readable = wait_readable(options_.read_timeout);
      if (body && !options_.on_body_wait(false)) return -1;
      if (!readable) {
        // A request that stopped arriving: it is told so, once.
        if (phase_ != Phase::kIdle)
          answer_and_drop(408, "Request Timeout", "timeout",
                          phase_ == Phase::kHead ? "the request's headers did not arrive in time"
                                                 : "the request's body did not arrive in time");
        return -1;
      }
      n = receive_now();
    }
    if (n <= 0) return n;
    begin_ = 0;
    end_ = static_cast<std::size_t>(n);
  }
  std::size_t n = std::min(size, end_ - begin_);
  if (phase_ == Phase::kHead) {
    if (head_read_ + n > options_.max_head_bytes) {
      answer_and_drop(431, "Request Header Fields Too Large", "too_large",
                      "the request's line and headers exceed " + std::to_string(options_.max_head_bytes) + " bytes");
      return -1;
    }
    head_read_ += n;
  } else if (phase_ == Phase::kBody) {
    body_read_ += n;
  }
  std::memcpy(ptr, buffer_.get() + begin_, n);
  begin_ += n;
  return static_cast<ssize_t>(n);
}

std::string ConnectionStream::closing_head(std::string_view head) {
  const std::size_t end = head.find("\r\n\r\n");
  const std::size_t first_line = head.find("\r\n");
  if (end == std::string_view::npos || first_line == std::string_view::npos) return std::string(head);
  std::string out(head.substr(0, first_line + 2));
  for (std::size_t at = first_line + 2; at < end + 2;) {
    const std::size_t next = head.find("\r\n", at);
    const std::string_view line = head.substr(at, next - at);
    if (!starts_with_nocase(line, "connection:") && !starts_with_nocase(line, "keep-alive:")) {
      out.append(line);
      out += "\r\n";
    }
    at = next + 2;
  }
  out += "Connection: close\r\n\r\n";
  out.append(head.substr(end + 4));
  return out;
}

ssize_t ConnectionStream::send_once(const char* ptr, size_t size) {
  if (!ssl_) {
    if (!is_writable()) return -1;
    ssize_t n = 0;
    do {
      n = ::send(sock_, ptr, size, MSG_NOSIGNAL);
    } while (n < 0 && errno == EINTR);
    return n;
  }
  const auto deadline = Clock::now() + options_.write_timeout;
  for (;;) {
    const int n = SSL_write(ssl_, ptr, static_cast<int>(std::min<std::size_t>(size, 1 << 30)));
    if (n > 0) return n;
    const int error = SSL_get_error(ssl_, n);
    const short events = error == SSL_ERROR_WANT_WRITE ? POLLOUT : error == SSL_ERROR_WANT_READ ? POLLIN : 0;
    if (events == 0 || !poll_for(sock_, events, deadline - Clock::now())) return -1;
  }
}

bool ConnectionStream::send_all(const char* ptr, size_t size) {
  for (std::size_t sent = 0; sent < size;) {
    const ssize_t n = send_once(ptr + sent, size - sent);
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return true;
}

ssize_t ConnectionStream::write(const char* ptr, size_t size) {
  if (dropped_) return -1;
  if (!reply_started_ && phase_ != Phase::kIdle) {
    const std::string_view head(ptr, size);
    const int status = status_of(head);
    if (status >= 200) {  // not an interim "100 Continue"
      reply_started_ = true;
      const bool unparsed = phase_ == Phase::kHead;  // the headers never parsed: 400, 414
      const bool body_unread = status >= 400 && !body_complete();
      must_close_ = unparsed || body_unread || says_close(head);
      if (must_close_ && head.find("\r\n\r\n") != std::string_view::npos) {
        const std::string closing = closing_head(head);
        return send_all(closing.data(), closing.size()) ? static_cast<ssize_t>(size) : -1;
      }
    }
  }
  return send_once(ptr, size);
}

void ConnectionStream::answer_and_drop(int status, const char* reason, const std::string& code,
                                       const std::string& message) {
  if (dropped_) return;
  if (!reply_started_) {
    reply_started_ = true;
    const std::string body = nlohmann::json{{"error", {{"code", code}, {"message", message}}}}.dump();
    const std::string reply = "HTTP/1.1 " + std::to_string(status) + " " + reason +
                              "\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
                              "\r\nConnection: close\r\n\r\n" + body;
    send_all(reply.data(), reply.size());  // false: the client went; nothing more to say
  }
  answered_status_ = status;
  must_close_ = true;
  dropped_ = true;
}

void ConnectionStream::get_remote_ip_and_port(std::string& ip, int& port) const { address_of(sock_, true, ip, port); }
void ConnectionStream::get_local_ip_and_port(std::string& ip, int& port) const { address_of(sock_, false, ip, port); }

}  // namespace orbatlas
