#pragma once
// An httplib::Server whose connections cannot be held by slow clients nor
// desynchronised by malformed or refused requests.
//
// httplib bounds each read (5 s) but not a whole request: a client sending one
// header line every two seconds held an HTTP thread forever, and ten of them
// held all of them (health checks included). This server runs each connection
// on a stream of its own (server/http/connection_stream.h) with deadlines:
//   - a request's line and headers must arrive within `header_timeout_s` of its
//     first byte and take at most `max_head_bytes` (else 408 or 431, closed);
//   - its body within `body_timeout_s` of its headers and at a rate of at least
//     `min_body_rate_bytes_s` after a grace of `header_timeout_s` (uploads:
//     the rate only), else 408 and closed;
//   - at most `max_waiting` connections may wait for a request (idle kept-alive
//     ones, or ones whose headers are still coming) or for their body's next
//     bytes: beyond that the one waiting longest is closed, so the other
//     threads stay free for requests that arrive whole (a health check always
//     gets a thread, within `fresh_grace_s`). Never chosen: one whose client
//     has sent bytes its thread has not read yet (a request in, its thread not
//     yet scheduled), and a fresh connection (no request yet) before it has
//     waited `fresh_grace_s`: a browser opens six at once for a page's scripts
//     and, unlike on a kept-alive connection, does not send a request again
//     when a fresh one closes; on a busy machine the page lost a script. A
//     room keeper thread closes such a one once its grace is over. A request whose headers were already in when its
//     connection was closed this way gets no reply, and one with a body (a
//     frame) is never handled: the client cannot read a reply on that
//     connection and sends the request again on a new one
//     (client/api/server_client.cc), so handling the first would take a frame
//     twice. (A request without a body, a GET, may still run; it changes nothing.)
//   - after a reply that leaves the connection out of step (a request whose
//     headers did not parse, an error reply before the body was read) the
//     connection is closed, and the reply says so: the unread bytes are never
//     read as a request. A request with neither Content-Length nor
//     Transfer-Encoding has no body.
// Writing a reply is bounded by httplib's write timeout only (a slow handler is
// not the client's fault).
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "core/server/metrics_registry.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas {

class TlsContext;  // server/http/tls_context.h

struct ConnectionLimits {
  double header_timeout_s = 10.0;
  double body_timeout_s = 60.0;
  double min_body_rate_bytes_s = 16 * 1024;  // 0: none
  std::size_t max_head_bytes = 32 * 1024;
  std::size_t max_waiting = 4;
  // A fresh connection (no request yet) is not closed for room before this.
  double fresh_grace_s = 0.25;
  std::string unbounded_body_prefix = "/v1/uploads";  // paths whose body has no total deadline
  // Requests one kept-alive connection may carry before the server closes it.
  // httplib's 5 made a live session (20 frames a second) open a new connection
  // four times a second (34 connections for 8 s of one session; 2 with this).
  // Idle connections are still closed after the keep-alive timeout, and for
  // room (max_waiting).
  std::size_t keep_alive_requests = 1000000;
};

struct ConnectionStats {
  std::uint64_t connections = 0;
  std::uint64_t closed_slow = 0;           // past a header or body deadline
  std::uint64_t closed_for_room = 0;       // the longest-waiting, when too many waited
  std::uint64_t dropped = 0;               // requests whose connection was closed for room before they were handled
  std::uint64_t closed_after_refusal = 0;  // after a malformed request, or an error reply before the body was read
};

class GuardedHttpServer : public httplib::Server {
 public:
  // `tls`: every connection speaks TLS with its certificate (null: plain HTTP).
  explicit GuardedHttpServer(ConnectionLimits limits = {}, std::shared_ptr<const TlsContext> tls = nullptr);
  ~GuardedHttpServer() override;
  GuardedHttpServer(const GuardedHttpServer&) = delete;
  GuardedHttpServer& operator=(const GuardedHttpServer&) = delete;
  bool tls() const { return tls_ != nullptr; }
  ConnectionStats connection_stats() const;
  // The figures as Prometheus metrics (HttpApiOptions::extra_metrics).
  std::vector<prometheus::MetricFamily> metrics() const;

  // A connection's phase, shared between its thread and the others (which may
  // close it to make room). Public for the stream in the .cc file.
  struct Connection {
    socket_t sock = INVALID_SOCKET;
    bool waiting = true;  // for a request (idle, or its headers coming)
    std::chrono::steady_clock::time_point waiting_since;
    bool closed = false;  // shut down by another thread
    bool fresh = true;    // no request's headers came yet
  };

 private:
  bool process_and_close_socket(socket_t sock) override;
  // Marks the connection waiting (or not); when too many wait, shuts the one
  // waiting longest down. False when this connection itself was shut down so.
  // `since`: when it started waiting (default: now).
  bool set_waiting(std::uint64_t id, bool waiting,
                   std::optional<std::chrono::steady_clock::time_point> since = std::nullopt);
  // While more than max_waiting wait, shuts down the one waiting longest that
  // may be closed (not `keep`). Under mutex_. Returns when the next fresh one
  // may be closed if still too many wait (nullopt: not needed, or none can).
  std::optional<std::chrono::steady_clock::time_point> make_room(std::optional<std::uint64_t> keep);
  // The room keeper's loop: make_room whenever a fresh connection's grace ends
  // while too many wait.
  void keep_room();
  // The body's length from the headers (nullopt: chunked, or a length that is
  // refused before it is read); a request with neither header gets
  // Content-Length 0.
  static std::optional<std::uint64_t> body_length(httplib::Request& req);
  std::optional<std::chrono::steady_clock::time_point> body_deadline(const httplib::Request& req,
                                                                     std::optional<std::uint64_t> bytes) const;

  const ConnectionLimits limits_;
  const std::shared_ptr<const TlsContext> tls_;
  mutable std::mutex mutex_;  // guards connections_, next_id_, stats_, stopping_ (the only lock here)
  std::condition_variable room_changed_;
  bool stopping_ = false;
  std::map<std::uint64_t, Connection> connections_;
  std::uint64_t next_id_ = 0;
  ConnectionStats stats_;
  mutable MetricsRegistry metrics_;  // synced with stats_ when asked (under mutex_)
  prometheus::Counter& connections_total_ =
      metrics_.counter("orbatlas_http_connections_total", "HTTP connections accepted.");
  prometheus::Counter& closed_slow_ = metrics_.counter(
      "orbatlas_http_connections_closed_total",
      "Connections the server closed: past a header or body deadline (slow), the longest-waiting one when too many "
      "waited (room), or after a malformed request or an error reply before the body was read (refused).",
      {{"reason", "slow"}});
  prometheus::Counter& closed_for_room_ = metrics_.counter(
      "orbatlas_http_connections_closed_total",
      "Connections the server closed: past a header or body deadline (slow), the longest-waiting one when too many "
      "waited (room), or after a malformed request or an error reply before the body was read (refused).",
      {{"reason", "room"}});
  prometheus::Counter& closed_after_refusal_ = metrics_.counter(
      "orbatlas_http_connections_closed_total",
      "Connections the server closed: past a header or body deadline (slow), the longest-waiting one when too many "
      "waited (room), or after a malformed request or an error reply before the body was read (refused).",
      {{"reason", "refused"}});
  prometheus::Counter& dropped_ = metrics_.counter(
      "orbatlas_http_requests_dropped_total",
      "Requests whose headers had arrived when their connection was closed for room: no reply, and never handled "
      "when they have a body (the client sends them again on a new connection).");
  std::thread room_keeper_;  // last: started once the members it uses exist
};

}  // namespace orbatlas
