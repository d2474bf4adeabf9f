#include "core/common/worker_errors.h"

#include <utility>

#include "core/common/log.h"

namespace orbatlas {
namespace {

std::string message_of(const std::exception_ptr& error) {
  try {
    if (error) std::rethrow_exception(error);
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "an unknown error";
  }
  return "no error";
}

}  // namespace

WorkerErrors::WorkerErrors(std::string worker, std::size_t fatal_after)
    : worker_(std::move(worker)), fatal_after_(fatal_after == 0 ? 1 : fatal_after) {}

bool WorkerErrors::record(std::string_view unit, std::exception_ptr error) {
  const std::string what = message_of(error);
  bool fatal = false;
  {
    std::lock_guard lock(mutex_);
    ++counts_.errors;
    counts_.last = what;
    if (++in_a_row_ >= fatal_after_ && !fatal_) {
      counts_.fatal = true;
      fatal_ = std::make_exception_ptr(
          WorkerFailed(worker_ + " failed " + std::to_string(in_a_row_) + " times in a row; last: " + what));
    }
    fatal = counts_.fatal;
  }
  log_warn(worker_ + ": " + std::string(unit) + " given up after an error" +
           (fatal ? " (too many in a row: the map is taken as unusable)" : " (the worker goes on)") + ": " + what);
  return fatal;
}

void WorkerErrors::succeeded() {
  std::lock_guard lock(mutex_);
  in_a_row_ = 0;
}

WorkerErrorCounts WorkerErrors::counts() const {
  std::lock_guard lock(mutex_);
  return counts_;
}

std::exception_ptr WorkerErrors::fatal_error() const {
  std::lock_guard lock(mutex_);
  return fatal_;
}

}  // namespace orbatlas
