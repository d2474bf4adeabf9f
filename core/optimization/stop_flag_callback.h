#pragma once
// A Ceres iteration callback that ends the solve when a shared flag is raised
// (e.g. local mapping interrupted by a new keyframe). The parameters keep the
// last accepted iterate.
#include <ceres/iteration_callback.h>

#include <atomic>

namespace orbatlas {

class StopFlagCallback final : public ceres::IterationCallback {
 public:
  explicit StopFlagCallback(const std::atomic<bool>* stop) : stop_(stop) {}  // null: never stops
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& /*summary*/) override {
    return stopped() ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
  }
  bool stopped() const { return stop_ != nullptr && stop_->load(std::memory_order_relaxed); }
  const std::atomic<bool>* flag() const { return stop_; }  // null: never stops

 private:
  const std::atomic<bool>* stop_;  // not owned
};

}  // namespace orbatlas
