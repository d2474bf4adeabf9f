#pragma once
// One thread running tasks in order from a bounded queue, shared by several
// producers (the map server's loop closing: one thread for every session,
// instead of one per session). Posting never blocks: a full queue refuses the
// task and the producer decides what that means. stop() lets the thread finish
// what is queued, then joins it; later posts are refused.
#include <functional>
#include <string>
#include <thread>

#include "core/common/bounded_queue.h"

namespace orbatlas {

class SerialWorker {
 public:
  // `nice`: the thread's nice value (thread_priority.h; 0: as created);
  // `name`: the thread's name (thread_name.h; empty: the process's).
  explicit SerialWorker(std::size_t capacity, int nice = 0, std::string name = {});
  ~SerialWorker();  // stop()
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;

  // False when the queue is full or the worker stopped (the task is dropped).
  // A task must not throw (an escaping exception is logged and dropped).
  bool try_post(std::function<void()> task);
  void stop();  // idempotent
  std::size_t queued() const { return queue_.size(); }

 private:
  BoundedQueue<std::function<void()>> queue_;
  std::thread thread_;  // last
};

}  // namespace orbatlas
