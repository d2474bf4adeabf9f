#include "server/http/guarded_http_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <memory>
#include <optional>

namespace orbatlas {
namespace {

using Clock = std::chrono::steady_clock;

// Waits until `sock` is readable (or writable) for at most `timeout`.
bool wait_for(socket_t sock, short events, Clock::duration timeout) {
  if (timeout <= Clock::duration::zero()) return false;
  pollfd p{sock, events, 0};
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count();
  int r = 0;
  do {
    r = ::poll(&p, 1, static_cast<int>(std::max<long long>(1, std::min<long long>(ms, 1 << 30))));
  } while (r < 0 && errno == EINTR);
  return r > 0;
}

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

// A connection's stream: buffered reads that fail once the request's deadline
// has passed; writes bounded per call. Reads take what the socket holds, up to
// kReadBuffer bytes, without waiting when something is there: httplib reads a
// body 4 KiB at a time, and a wait (poll) and a recv per 4 KiB were 350
// system calls for one stereo frame of raw pixels (720 KiB).
class GuardedStream : public httplib::Stream {
 public:
  static constexpr std::size_t kReadBuffer = 256 * 1024;

  GuardedStream(socket_t sock, Clock::duration read_timeout, Clock::duration write_timeout)
      : sock_(sock), read_timeout_(read_timeout), write_timeout_(write_timeout), buffer_(new char[kReadBuffer]) {}

  void set_deadline(std::optional<Clock::time_point> deadline) { deadline_ = deadline; }
  // Every read and write fails from now on (what is buffered included).
  void drop() { dropped_ = true; }
  bool deadline_passed() const { return deadline_ && Clock::now() >= *deadline_; }
  bool has_buffered() const { return begin_ < end_; }

  bool is_readable() const override {
    if (has_buffered()) return true;
    Clock::duration wait = read_timeout_;
    if (deadline_) wait = std::min(wait, *deadline_ - Clock::now());
    return wait_for(sock_, POLLIN, wait);
  }
  bool is_writable() const override { return wait_for(sock_, POLLOUT, write_timeout_); }

  ssize_t read(char* ptr, size_t size) override {
    if (dropped_) return -1;
    if (!has_buffered()) {
      if (deadline_passed()) return -1;
      // What is there already, without a wait; else wait (bounded) and read.
      ssize_t n = receive(MSG_DONTWAIT);
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        if (!is_readable()) return -1;
        n = receive(0);
      }
      if (n <= 0) return n;
      begin_ = 0;
      end_ = static_cast<std::size_t>(n);
    }
    const std::size_t n = std::min(size, end_ - begin_);
    std::memcpy(ptr, buffer_.get() + begin_, n);
    begin_ += n;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (dropped_ || !is_writable()) return -1;
    ssize_t n = 0;
    do {
      n = ::send(sock_, ptr, size, MSG_NOSIGNAL);
    } while (n < 0 && errno == EINTR);
    return n;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override { address_of(sock_, true, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { address_of(sock_, false, ip, port); }
  socket_t socket() const override { return sock_; }

 private:
  ssize_t receive(int flags) {
    ssize_t n = 0;
    do {
      n = ::recv(sock_, buffer_.get(), kReadBuffer, flags);
    } while (n < 0 && errno == EINTR);
    return n;
  }

  socket_t sock_;
  Clock::duration read_timeout_, write_timeout_;
  std::optional<Clock::time_point> deadline_;
  std::unique_ptr<char[]> buffer_;
  std::size_t begin_ = 0, end_ = 0;
  bool dropped_ = false;
};

// Closes after the reply without resetting it: a request refused before its body
// was read (413, 401) leaves the body coming in, and closing with unread data
// sends a reset that can destroy the reply before the client reads it. So: end
// our side, then read and drop what still comes, for a bounded time and size.
void lingering_close(socket_t sock) {
  ::shutdown(sock, SHUT_WR);
  const auto until = Clock::now() + std::chrono::seconds(2);
  std::size_t drained = 0;
  char scratch[16384];
  while (drained < (64u << 20) && wait_for(sock, POLLIN, until - Clock::now())) {
    const ssize_t n = ::recv(sock, scratch, sizeof scratch, 0);
    if (n <= 0) break;
    drained += static_cast<std::size_t>(n);
  }
  ::close(sock);
}

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(std::max(0.0, s)));
}

}  // namespace

GuardedHttpServer::GuardedHttpServer(ConnectionLimits limits) : limits_(std::move(limits)) {
  set_keep_alive_max_count(std::max<std::size_t>(1, limits_.keep_alive_requests));
}

ConnectionStats GuardedHttpServer::connection_stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::vector<prometheus::MetricFamily> GuardedHttpServer::metrics() const {
  {
    std::lock_guard lock(mutex_);
    advance_counter_to(connections_total_, static_cast<double>(stats_.connections));
    advance_counter_to(closed_slow_, static_cast<double>(stats_.closed_slow));
    advance_counter_to(closed_for_room_, static_cast<double>(stats_.closed_for_room));
    advance_counter_to(dropped_, static_cast<double>(stats_.dropped));
  }
  return metrics_.collect();
}

bool GuardedHttpServer::set_waiting(std::uint64_t id, bool waiting) {
  std::lock_guard lock(mutex_);
  Connection& self = connections_.at(id);
  if (self.closed) return false;
  self.waiting = waiting;
  if (!waiting) return true;
  self.waiting_since = Clock::now();
  std::size_t count = 0;
  for (const auto& [_, c] : connections_) count += c.waiting && !c.closed ? 1 : 0;
  while (count > std::max<std::size_t>(1, limits_.max_waiting)) {
    // The one waiting longest (never this one: it has just started).
    Connection* oldest = nullptr;
    for (auto& [other, c] : connections_)
      if (other != id && c.waiting && !c.closed && (!oldest || c.waiting_since < oldest->waiting_since)) oldest = &c;
    if (!oldest) break;
    // Its thread is blocked in poll or recv on it: both return at once. The
    // descriptor stays open (its own thread closes it, after unregistering).
    ::shutdown(oldest->sock, SHUT_RDWR);
    oldest->closed = true;
    ++stats_.closed_for_room;
    --count;
  }
  return true;
}

bool GuardedHttpServer::process_and_close_socket(socket_t sock) {
  std::uint64_t id = 0;
  {
    std::lock_guard lock(mutex_);
    id = next_id_++;
    connections_[id] = Connection{sock, true, Clock::now(), false};
    ++stats_.connections;
  }
  GuardedStream stream(sock, std::chrono::seconds(read_timeout_sec_) + std::chrono::microseconds(read_timeout_usec_),
                       std::chrono::seconds(write_timeout_sec_) + std::chrono::microseconds(write_timeout_usec_));
  const Clock::duration header_timeout = seconds(limits_.header_timeout_s);
  const Clock::duration body_timeout = seconds(limits_.body_timeout_s);
  bool ret = false;
  bool slow = false;
  for (std::size_t left = std::max<std::size_t>(1, keep_alive_max_count_); left > 0 && svr_sock_ != INVALID_SOCKET;
       --left) {
    if (!set_waiting(id, true)) break;  // closed for room since the last request
    // Idle until the next request starts (httplib's keep-alive timeout).
    if (!stream.has_buffered() && !wait_for(sock, POLLIN, std::chrono::seconds(keep_alive_timeout_sec_))) break;
    stream.set_deadline(Clock::now() + header_timeout);
    bool connection_closed = false;
    ret = process_request(stream, left == 1, connection_closed, [&](httplib::Request& req) {
      // The headers are in: the request no longer waits; its body has a deadline of its own.
      if (!set_waiting(id, false)) {
        // Closed for room while its headers came in (they were already
        // received): its body cannot be read, so it is never handled, and the
        // client's resend on a new connection is the only one taken.
        stream.drop();
        std::lock_guard lock(mutex_);
        ++stats_.dropped;
        return;
      }
      const bool unbounded = req.path.rfind(limits_.unbounded_body_prefix, 0) == 0;
      stream.set_deadline(unbounded ? std::nullopt : std::optional<Clock::time_point>(Clock::now() + body_timeout));
    });
    slow = slow || stream.deadline_passed();
    stream.set_deadline(std::nullopt);
    if (!ret || connection_closed) break;
  }
  bool cut = slow;
  {
    std::lock_guard lock(mutex_);
    cut = cut || connections_.at(id).closed;
    if (slow && !connections_.at(id).closed) ++stats_.closed_slow;
    connections_.erase(id);  // before close: no other thread touches the descriptor any more
  }
  if (cut) {
    ::shutdown(sock, SHUT_RDWR);  // a slow or crowded-out client gets no more of our time
    ::close(sock);
  } else {
    lingering_close(sock);
  }
  return ret;
}

}  // namespace orbatlas
