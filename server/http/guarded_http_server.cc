#include "server/http/guarded_http_server.h"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "server/http/connection_stream.h"
#include "server/http/tls_context.h"

namespace orbatlas {
namespace {

using Clock = std::chrono::steady_clock;

// Closes after the reply without resetting it: a request refused before its body
// was read (413, 401) leaves the body coming in, and closing with unread data
// sends a reset that can destroy the reply before the client reads it. So: end
// our side, then read and drop what still comes, for a bounded time and size.
void lingering_close(socket_t sock, Clock::duration linger) {
  ::shutdown(sock, SHUT_WR);
  const auto until = Clock::now() + linger;
  std::size_t drained = 0;
  char scratch[16384];
  for (;;) {
    // What is there now, then (while the linger lasts) what still comes.
    ssize_t n = ::recv(sock, scratch, sizeof scratch, MSG_DONTWAIT);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) && poll_for(sock, POLLIN, until - Clock::now()))
      n = ::recv(sock, scratch, sizeof scratch, 0);
    if (n <= 0) break;
    drained += static_cast<std::size_t>(n);
    if (drained >= (64u << 20)) break;
  }
  ::close(sock);
}

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(std::max(0.0, s)));
}

// The client has closed its end (end of stream, or a reset, waiting to be
// read): the connection is not idle but over, and must not crowd out one that
// is (a thread that reaches its next wait late would otherwise close a live
// client's connection in its place).
bool peer_closed(socket_t sock) {
  pollfd p{sock, POLLIN, 0};
  if (::poll(&p, 1, 0) <= 0) return false;
  if ((p.revents & (POLLHUP | POLLERR)) != 0) return true;
  char c = 0;
  return ::recv(sock, &c, 1, MSG_PEEK | MSG_DONTWAIT) == 0;
}

// Bytes from the client are waiting to be read (or its end has closed): its
// thread is about to take them, so the connection is not idle, only not yet
// scheduled. On a busy machine a browser's fresh connection sat so with its
// request in, was closed for room, and the page lost a script.
bool readable_now(socket_t sock) {
  pollfd p{sock, POLLIN, 0};
  return ::poll(&p, 1, 0) > 0;
}

}  // namespace

GuardedHttpServer::GuardedHttpServer(ConnectionLimits limits, std::shared_ptr<const TlsContext> tls)
    : limits_(std::move(limits)), tls_(std::move(tls)) {
  set_keep_alive_max_count(std::max<std::size_t>(1, limits_.keep_alive_requests));
  room_keeper_ = std::thread([this] { keep_room(); });
}

GuardedHttpServer::~GuardedHttpServer() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  room_changed_.notify_all();
  room_keeper_.join();
}

void GuardedHttpServer::keep_room() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    const std::optional<Clock::time_point> next = make_room(std::nullopt);
    if (next)
      room_changed_.wait_until(lock, *next);
    else
      room_changed_.wait(lock);
  }
}

std::optional<Clock::time_point> GuardedHttpServer::make_room(std::optional<std::uint64_t> keep) {
  const std::size_t allowed = std::max<std::size_t>(1, limits_.max_waiting);
  // The connections taking room: waiting with nothing to read. One with something
  // to read (a request, or the peer's close) is about to be served or to end.
  std::vector<std::pair<std::uint64_t, Connection*>> idle;
  for (auto& [id, c] : connections_)
    if (c.waiting && !c.closed && !readable_now(c.sock)) idle.emplace_back(id, &c);
  const Clock::time_point now = Clock::now();
  const Clock::duration grace = seconds(limits_.fresh_grace_s);
  const auto in_grace = [&](const Connection& c) { return c.fresh && now - c.waiting_since < grace; };
  std::size_t count = idle.size();
  while (count > allowed) {
    // The one waiting longest that may be closed.
    Connection* oldest = nullptr;
    for (const auto& [id, c] : idle) {
      if (id == keep || c->closed || in_grace(*c)) continue;
      if (!oldest || c->waiting_since < oldest->waiting_since) oldest = c;
    }
    if (!oldest) break;
    // Its thread is blocked in poll or recv on it: both return at once. The
    // descriptor stays open (its own thread closes it, after unregistering).
    ::shutdown(oldest->sock, SHUT_RDWR);
    oldest->closed = true;
    ++stats_.closed_for_room;
    --count;
  }
  if (count <= allowed) return std::nullopt;
  // Still too many: the next fresh one whose grace ends.
  std::optional<Clock::time_point> next;
  for (const auto& [_, c] : idle)
    if (!c->closed && in_grace(*c)) next = std::min(next.value_or(Clock::time_point::max()), c->waiting_since + grace);
  return next;
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
    advance_counter_to(closed_after_refusal_, static_cast<double>(stats_.closed_after_refusal));
  }
  return metrics_.collect();
}

bool GuardedHttpServer::set_waiting(std::uint64_t id, bool waiting, std::optional<Clock::time_point> since) {
  std::lock_guard lock(mutex_);
  Connection& self = connections_.at(id);
  if (self.closed) return false;
  self.waiting = waiting;
  if (!waiting) {
    self.fresh = false;
    return true;
  }
  self.waiting_since = since.value_or(Clock::now());
  // Too many wait and none may be closed yet: the keeper closes one when it may.
  if (make_room(id)) room_changed_.notify_one();
  return true;
}

std::optional<std::uint64_t> GuardedHttpServer::body_length(httplib::Request& req) {
  if (req.has_header("Transfer-Encoding")) return std::nullopt;  // chunked (or refused before it is read)
  if (!req.has_header("Content-Length")) {
    // No length and no encoding: no body (RFC 9112, 6.3), not "until the
    // connection closes".
    req.set_header("Content-Length", "0");
    return 0;
  }
  const std::string text = req.get_header_value("Content-Length");
  std::uint64_t bytes = 0;
  if (text.empty() || text.size() > 19) return std::nullopt;
  for (const char c : text) {
    if (c < '0' || c > '9') return std::nullopt;  // refused before it is read
    bytes = bytes * 10 + static_cast<std::uint64_t>(c - '0');
  }
  return bytes;
}

std::optional<Clock::time_point> GuardedHttpServer::body_deadline(const httplib::Request& req,
                                                                  std::optional<std::uint64_t> bytes) const {
  const bool unbounded = req.path.rfind(limits_.unbounded_body_prefix, 0) == 0;
  const auto now = Clock::now();
  std::optional<Clock::duration> allowed;
  if (bytes && limits_.min_body_rate_bytes_s > 0)
    allowed =
        seconds(std::min(1e6, limits_.header_timeout_s + static_cast<double>(*bytes) / limits_.min_body_rate_bytes_s));
  if (!unbounded) allowed = std::min(allowed.value_or(Clock::duration::max()), seconds(limits_.body_timeout_s));
  if (!allowed) return std::nullopt;
  return now + *allowed;
}

bool GuardedHttpServer::process_and_close_socket(socket_t sock) {
  std::uint64_t id = 0;
  {
    std::lock_guard lock(mutex_);
    id = next_id_++;
    connections_[id] = Connection{sock, true, Clock::now(), false};
    ++stats_.connections;
  }
  std::optional<Clock::time_point> headers_at;
  ConnectionStream::Options stream_options;
  stream_options.read_timeout = std::chrono::seconds(read_timeout_sec_) + std::chrono::microseconds(read_timeout_usec_);
  stream_options.write_timeout =
      std::chrono::seconds(write_timeout_sec_) + std::chrono::microseconds(write_timeout_usec_);
  stream_options.max_head_bytes = limits_.max_head_bytes;
  // A body that makes the stream wait counts as waiting since its headers
  // came: a slow one is crowded out like a slow header.
  stream_options.on_body_wait = [this, id, &headers_at](bool waiting) { return set_waiting(id, waiting, headers_at); };
  stream_options.tls = tls_ ? tls_->native() : nullptr;
  ConnectionStream stream(sock, stream_options);
  const Clock::duration header_timeout = seconds(limits_.header_timeout_s);
  bool ret = false;
  bool slow = false, refused = false;
  // A TLS client has the header timeout for its handshake (it waits meanwhile).
  const bool shook_hands = stream.handshake(Clock::now() + header_timeout);
  for (std::size_t left = std::max<std::size_t>(1, keep_alive_max_count_); left > 0 && svr_sock_ != INVALID_SOCKET;
       --left) {
    if (!shook_hands || (!stream.has_buffered() && peer_closed(sock))) break;
    if (!set_waiting(id, true)) break;  // closed for room since the last request
    // Idle until the next request starts (httplib's keep-alive timeout).
    if (!stream.has_buffered() && !poll_for(sock, POLLIN, std::chrono::seconds(keep_alive_timeout_sec_))) break;
    stream.start_request(Clock::now() + header_timeout);
    bool connection_closed = false;
    ret = process_request(stream, left == 1, connection_closed, [&](httplib::Request& req) {
      // The headers are in: the request no longer waits; its body has a deadline of its own.
      headers_at = Clock::now();
      if (!set_waiting(id, false)) {
        // Closed for room while its headers came in (they were already
        // received): its body cannot be read, so it is never handled, and the
        // client's resend on a new connection is the only one taken.
        stream.drop();
        std::lock_guard lock(mutex_);
        ++stats_.dropped;
        return;
      }
      const std::optional<std::uint64_t> bytes = body_length(req);
      stream.headers_received(bytes, body_deadline(req, bytes));
    });
    slow = slow || stream.answered_status() == 408;
    refused = refused || (stream.must_close() && !slow);
    if (!ret || connection_closed || stream.must_close()) break;
  }
  bool crowded_out = false;
  {
    std::lock_guard lock(mutex_);
    crowded_out = connections_.at(id).closed;
    if (slow && !crowded_out) ++stats_.closed_slow;
    if (refused && !crowded_out) ++stats_.closed_after_refusal;
    connections_.erase(id);  // before close: no other thread touches the descriptor any more
  }
  stream.close_notify();
  if (crowded_out) {
    ::shutdown(sock, SHUT_RDWR);  // a crowded-out client gets no more of our time
    ::close(sock);
  } else {
    // A slow client gets its 408 and no wait for what it may still send.
    lingering_close(sock, slow ? Clock::duration::zero() : std::chrono::seconds(2));
  }
  return ret;
}

}  // namespace orbatlas
