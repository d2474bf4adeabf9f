#pragma once
// The building block of every background worker (local mapping, loop closing,
// map merging): a bounded queue of work items, the thread that processes them
// one at a time (its own, or a SerialWorker shared with other workers), the
// count of items handed in and not yet done, a wait for "idle", a pause between
// items, and what happens when an item fails (WorkerErrors: given up, logged,
// counted; a run of failures becomes the fatal error that push(),
// wait_until_idle() and finish() raise to the feeding session).
//
// The owner constructs its QueueWorker last (the thread starts in the
// constructor and the handler uses the owner's members) and lets it be
// destroyed first. The handler runs on the worker thread; it may throw.
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "core/common/bounded_queue.h"
#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/serial_worker.h"
#include "core/common/thread_name.h"
#include "core/common/thread_priority.h"
#include "core/common/worker_errors.h"

namespace orbatlas {

struct QueueWorkerOptions {
  std::string name = "worker";  // in log lines ("local mapping")
  std::size_t capacity = 8;     // items waiting (push blocks, try_push refuses beyond it)
  // Failures in a row that make the error fatal; kNeverFatal for a worker whose
  // failures concern one request only (the server's map merging).
  std::size_t fatal_after = 20;
  static constexpr std::size_t kNeverFatal = std::numeric_limits<std::size_t>::max();
  // When set, items run as tasks on this thread (shared with other workers)
  // instead of a thread of the worker's own; its queue then bounds them, and
  // pause() must not be used (it would hold up the other workers).
  std::shared_ptr<SerialWorker> shared;
  // The nice value of a thread of its own (thread_priority.h; 0: as created).
  int nice = 0;

  static QueueWorkerOptions own_thread(std::string name, std::size_t capacity, std::size_t fatal_after = 20,
                                       int nice = 0) {
    QueueWorkerOptions o;
    o.name = std::move(name);
    o.capacity = capacity;
    o.fatal_after = fatal_after;
    o.nice = nice;
    return o;
  }
};

template <class T>
class QueueWorker {
 public:
  using Handler = std::function<void(T& item)>;
  // What an item is, for the error log ("keyframe 12").
  using Describe = std::function<std::string(const T& item)>;

  QueueWorker(QueueWorkerOptions options, Handler handler, Describe describe)
      : options_(std::move(options)),
        handler_(std::move(handler)),
        describe_(std::move(describe)),
        errors_(options_.name, options_.fatal_after),
        queue_(options_.capacity) {
    ORBATLAS_CHECK(handler_ != nullptr, "a queue worker needs a handler");
    if (!options_.shared)
      thread_ = std::thread([this] {
        set_current_thread_nice(options_.nice);
        set_current_thread_name(options_.name);
        run();
      });
  }
  ~QueueWorker() {
    try {
      finish();
    } catch (const std::exception& e) {
      log_warn(options_.name + " stopped with an error: " + e.what());
    }
  }
  QueueWorker(const QueueWorker&) = delete;
  QueueWorker& operator=(const QueueWorker&) = delete;

  // Blocks while the queue is full. False once the worker is finishing
  // (the item is dropped); raises the fatal error when there is one.
  bool push(T item) {
    if (!enter()) return false;
    if (options_.shared) return post(std::move(item));
    if (queue_.push(std::move(item))) return true;
    leave();
    return false;
  }
  // Never blocks: false (item dropped) when the queue is full or the worker is
  // finishing. For producers that must not wait on this worker. Never raises.
  bool try_push(T item) {
    {
      std::lock_guard lock(mutex_);
      if (closed_) return false;
      ++in_flight_;
    }
    if (options_.shared) return post(std::move(item));
    if (queue_.try_push(std::move(item))) return true;
    leave();
    return false;
  }

  // Waits until every item handed in is done; raises the fatal error.
  void wait_until_idle() const {
    std::unique_lock lock(mutex_);
    idle_cv_.wait(lock, [&] { return in_flight_ == 0; });
    if (fatal_) std::rethrow_exception(fatal_);
  }
  // Stops processing between items: what is already handed in is processed
  // first, then nothing runs until resume(). pause_requested() turns true at
  // once (producers stop feeding). Returns once paused. Own thread only.
  void pause() {
    ORBATLAS_CHECK(!options_.shared, "pause() on a worker without a thread of its own");
    std::unique_lock lock(mutex_);
    pause_requested_ = true;
    idle_cv_.wait(lock, [&] { return in_flight_ == 0; });
    paused_ = true;
  }
  void resume() {
    std::lock_guard lock(mutex_);
    paused_ = false;
    pause_requested_ = false;
    idle_cv_.notify_all();
  }
  bool pause_requested() const {
    std::lock_guard lock(mutex_);
    return pause_requested_;
  }

  // Processes what is handed in, then stops (idempotent); later pushes are
  // refused. Raises the fatal error once.
  void finish() { stop_after(/*discard=*/false); }
  // Like finish(), but items still queued are dropped unprocessed (counted in
  // discarded()); the one in progress completes.
  void stop() { stop_after(/*discard=*/true); }

  bool idle() const {
    std::lock_guard lock(mutex_);
    return in_flight_ == 0;
  }
  std::size_t in_flight() const {  // handed in and not yet done
    std::lock_guard lock(mutex_);
    return in_flight_;
  }
  std::size_t queued() const { return options_.shared ? options_.shared->queued() : queue_.size(); }
  std::size_t discarded() const {
    std::lock_guard lock(mutex_);
    return discarded_;
  }
  WorkerErrorCounts errors() const { return errors_.counts(); }

  // Counts and logs an error of work the owner runs outside the handler for
  // this worker (loop closing's global adjustment); call from a catch block.
  void record_failure(const std::string& unit) { record(unit, std::current_exception()); }

 private:
  bool enter() {
    std::lock_guard lock(mutex_);
    if (fatal_) std::rethrow_exception(fatal_);
    if (closed_) return false;
    ++in_flight_;
    return true;
  }
  void leave() {
    std::lock_guard lock(mutex_);
    --in_flight_;
    idle_cv_.notify_all();
  }
  bool post(T item) {
    // The task holds the item; the worker outlives it (finish() waits for in_flight_ == 0).
    auto shared_item = std::make_shared<T>(std::move(item));
    if (options_.shared->try_post([this, shared_item] { run_one(*shared_item); })) return true;
    leave();
    return false;
  }
  void record(const std::string& unit, std::exception_ptr error) {
    if (!errors_.record(unit, std::move(error))) return;
    std::lock_guard lock(mutex_);
    if (!fatal_) fatal_ = errors_.fatal_error();
  }

  void run() {
    while (auto item = queue_.pop()) run_one(*item);
  }
  void run_one(T& item) {
    bool discard = false;
    {
      // An item handed in just as a pause began waits for the resume.
      std::unique_lock lock(mutex_);
      idle_cv_.wait(lock, [&] { return !paused_; });
      discard = discard_;
      if (discard) ++discarded_;
    }
    if (!discard) {
      try {
        handler_(item);
        errors_.succeeded();
      } catch (...) {
        // The item is given up as far as it went; the next one runs as usual.
        record(describe_ ? describe_(item) : "an item", std::current_exception());
      }
    }
    [[maybe_unused]] const T dropped = std::move(item);  // the worker's reference goes before it reports idle
    leave();
  }
  void stop_after(bool discard) {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
      if (discard) discard_ = true;
    }
    queue_.close();
    if (thread_.joinable()) thread_.join();
    std::unique_lock lock(mutex_);
    // On a shared thread: wait for this worker's items still queued there.
    idle_cv_.wait(lock, [&] { return in_flight_ == 0; });
    if (fatal_) std::rethrow_exception(std::exchange(fatal_, nullptr));
  }

  const QueueWorkerOptions options_;
  const Handler handler_;
  const Describe describe_;
  WorkerErrors errors_;
  BoundedQueue<T> queue_;  // own thread only

  mutable std::mutex mutex_;  // leaf: guards what follows
  mutable std::condition_variable idle_cv_;
  std::size_t in_flight_ = 0;
  std::size_t discarded_ = 0;
  bool closed_ = false, discard_ = false;
  bool pause_requested_ = false, paused_ = false;
  std::exception_ptr fatal_;

  std::thread thread_;  // last: started after everything above exists
};

}  // namespace orbatlas
