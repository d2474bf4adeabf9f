#pragma once
// One HTTP connection's stream (the server side of a socket), which keeps
// httplib's request parsing in step with the bytes on the wire:
//   - a request's line and headers may take at most `max_head_bytes`: past
//     that the stream answers 431 itself and fails every later read and write;
//   - a request that stops arriving (its deadline passed, or no byte for the
//     read timeout) is answered 408 by the stream itself, then the same;
//   - the head of each reply is checked as it is written: when the request's
//     headers never parsed (a 400 or 414 from httplib), or an error reply goes
//     out before the request's body was read whole (a refusal, 401/413/415),
//     or the reply already says `Connection: close`, the reply says
//     `Connection: close` exactly once (no `Keep-Alive`) and `must_close()`
//     tells the server not to read another request from the connection: the
//     unread bytes (a body, or what followed a malformed line) are never taken
//     for a request.
// Reads take what the socket holds, up to kReadBuffer bytes, without waiting
// when something is there: httplib reads a body 4 KiB at a time, and a wait
// (poll) and a recv per 4 KiB were 350 system calls for one stereo frame of raw
// pixels (720 KiB).
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

struct ssl_st;
struct ssl_ctx_st;

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas {

// Waits until `sock` has `events` (POLLIN, POLLOUT) for at most `timeout`.
bool poll_for(socket_t sock, short events, std::chrono::steady_clock::duration timeout);

class ConnectionStream : public httplib::Stream {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr std::size_t kReadBuffer = 256 * 1024;

  struct Options {
    Clock::duration read_timeout = std::chrono::seconds(5);  // one read without a byte
    Clock::duration write_timeout = std::chrono::seconds(5);
    std::size_t max_head_bytes = 32 * 1024;  // a request's line and headers
    // Called with true before the stream waits for a body's bytes and false
    // once they came; false back means the connection was closed meanwhile.
    std::function<bool(bool waiting)> on_body_wait;
    // TLS (server/http/tls_context.h): the connection is encrypted; null: plain.
    ssl_ctx_st* tls = nullptr;
  };

  ConnectionStream(socket_t sock, Options options);
  ~ConnectionStream() override;
  ConnectionStream(const ConnectionStream&) = delete;
  ConnectionStream& operator=(const ConnectionStream&) = delete;

  // The TLS handshake, by `deadline` (a plain connection: nothing to do). False:
  // the client is not speaking TLS, or too slowly; close the connection.
  bool handshake(Clock::time_point deadline);
  // Tells a TLS client the connection ends (close_notify), without waiting.
  void close_notify();

  // A new request starts (its first byte is there): its line and headers are
  // due by `deadline`.
  void start_request(Clock::time_point deadline);
  // Its headers parsed: `body_bytes` more belong to it (nullopt: chunked),
  // due by `deadline` (nullopt: only each read is bounded).
  void headers_received(std::optional<std::uint64_t> body_bytes, std::optional<Clock::time_point> deadline);
  // After the request: whether the connection must be closed now (its reply
  // said so), and whether the stream answered it itself (408, 431).
  bool must_close() const { return must_close_; }
  int answered_status() const { return answered_status_; }
  // Every read and write fails from now on (what is buffered included).
  void drop() { dropped_ = true; }
  bool has_buffered() const;

  bool is_readable() const override;
  bool is_writable() const override;
  ssize_t read(char* ptr, size_t size) override;
  ssize_t write(const char* ptr, size_t size) override;
  void get_remote_ip_and_port(std::string& ip, int& port) const override;
  void get_local_ip_and_port(std::string& ip, int& port) const override;
  socket_t socket() const override { return sock_; }

  // The reply head as it goes out when the connection closes after it: every
  // Connection and Keep-Alive line replaced by one `Connection: close`.
  static std::string closing_head(std::string_view head);

 private:
  enum class Phase { kIdle, kHead, kBody };
  // What the connection holds now, without waiting: bytes (> 0), 0 when the
  // client closed, -1 with errno EAGAIN when nothing is there yet, else -1.
  ssize_t receive_now();
  ssize_t send_once(const char* ptr, size_t size);
  bool send_all(const char* ptr, size_t size);
  bool wait_readable(Clock::duration wait) const;
  bool body_complete() const { return expected_body_ && body_read_ >= *expected_body_; }
  // Writes a whole JSON error reply, then fails everything after it.
  void answer_and_drop(int status, const char* reason, const std::string& code, const std::string& message);

  socket_t sock_;
  Options options_;
  ssl_st* ssl_ = nullptr;
  std::unique_ptr<char[]> buffer_;
  std::size_t begin_ = 0, end_ = 0;
  bool dropped_ = false;

  // The request in progress.
  Phase phase_ = Phase::kIdle;
  std::optional<Clock::time_point> deadline_;
  std::size_t head_read_ = 0;
  std::optional<std::uint64_t> expected_body_;
  std::uint64_t body_read_ = 0;
  bool reply_started_ = false;
  bool must_close_ = false;
  int answered_status_ = 0;
};

}  // namespace orbatlas
