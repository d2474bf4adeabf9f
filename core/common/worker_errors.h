#pragma once
// What a background worker (local mapping, loop closing, map merging) does with
// an error in one unit of its work: the unit is given up (its edits so far stay,
// each of them a complete step of the map model), the error is logged and
// counted, and the worker goes on with the next unit. Only a run of
// `fatal_after` failures in a row, which means the map itself is unusable,
// makes the error fatal for the session that feeds the worker.
#include <cstddef>
#include <exception>
#include <mutex>
#include <string>
#include <string_view>

#include "core/common/error.h"

namespace orbatlas {

// The fatal error: a worker gave up on its map (fatal_after failures in a row).
class WorkerFailed : public Error {
 public:
  using Error::Error;
};

struct WorkerErrorCounts {
  std::size_t errors = 0;  // units given up
  std::string last;        // the last error's message ("" when none)
  bool fatal = false;      // fatal_after failures in a row happened
};

class WorkerErrors {
 public:
  // `worker` names the worker in log lines ("local mapping").
  explicit WorkerErrors(std::string worker, std::size_t fatal_after = 20);

  // Logs and counts the error in flight (call from a catch block); `unit`
  // says what was given up ("keyframe 12"). Returns true when the error is now
  // fatal (fatal_after failures in a row).
  bool record(std::string_view unit, std::exception_ptr error);
  // A unit of work went through: resets the run of failures.
  void succeeded();

  WorkerErrorCounts counts() const;
  // The fatal error to raise to the session (null unless fatal).
  std::exception_ptr fatal_error() const;

 private:
  const std::string worker_;
  const std::size_t fatal_after_;
  mutable std::mutex mutex_;
  WorkerErrorCounts counts_;
  std::size_t in_a_row_ = 0;
  std::exception_ptr fatal_;
};

}  // namespace orbatlas
