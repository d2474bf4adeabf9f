#include "core/common/progress.h"

#include <unistd.h>

#include <cstdio>

namespace orbatlas {

Progress::Progress(std::string label, std::int64_t total, bool enabled)
    : label_(std::move(label)),
      total_(total),
      enabled_(enabled),
      tty_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {}

Progress::~Progress() { finish(); }

double Progress::elapsed_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::advance(std::int64_t n) {
  done_ += n;
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_print_).count();
  if (since < (tty_ ? 0.2 : 5.0)) return;
  std::unique_lock lock(print_mutex_, std::try_to_lock);
  if (!lock.owns_lock() || finished_) return;
  last_print_ = now;
  print(false);
}

void Progress::finish() {
  std::lock_guard lock(print_mutex_);
  if (finished_) return;
  finished_ = true;
  if (enabled_) print(true);
}

void Progress::print(bool final_line) {
  const std::int64_t done = done_.load();
  const double el = elapsed_s();
  const double pct = total_ > 0 ? 100.0 * static_cast<double>(done) / static_cast<double>(total_) : 0.0;
  const double eta =
      (done > 0 && total_ > done) ? el * static_cast<double>(total_ - done) / static_cast<double>(done) : 0.0;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s%s: %lld/%lld (%.0f%%) %.1fs elapsed%s", tty_ ? "\r" : "", label_.c_str(),
                static_cast<long long>(done), static_cast<long long>(total_), pct, el,
                final_line ? "" : (", eta " + std::to_string(static_cast<int>(eta)) + "s").c_str());
  std::fputs(buf, stderr);
  if (!tty_ || final_line) std::fputc('\n', stderr);
  std::fflush(stderr);
}

}  // namespace orbatlas
