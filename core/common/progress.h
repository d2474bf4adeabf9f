#pragma once
// Progress of long work on stderr: a refreshing line on a terminal, a line every
// few seconds otherwise (logs, CI). Thread-safe: workers may call advance().
#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace orbatlas {

class Progress {
 public:
  Progress(std::string label, std::int64_t total, bool enabled = true);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void advance(std::int64_t n = 1);
  void finish();  // prints the final line (idempotent)
  double elapsed_s() const;

 private:
  void print(bool final_line);

  std::string label_;
  std::int64_t total_;
  bool enabled_;
  bool tty_;
  std::atomic<std::int64_t> done_{0};
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_print_;
  std::mutex print_mutex_;
  bool finished_ = false;
};

}  // namespace orbatlas
