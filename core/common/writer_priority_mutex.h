#pragma once
// A shared mutex that lets a waiting writer in: once a thread waits in lock(),
// new shared owners wait until it has had its turn. std::shared_mutex on glibc
// prefers readers, so a map read by several sessions' frames one after the
// other (shared) would keep a merge or loop correction (exclusive) waiting for
// ever. Not recursive in either mode: a thread holding it shared must not take
// it shared again (a writer waiting in between would deadlock both).
// Meets the standard's SharedMutex requirements (std::unique_lock, std::shared_lock).
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <mutex>

namespace orbatlas {

class WriterPriorityMutex {
 public:
  WriterPriorityMutex() = default;
  WriterPriorityMutex(const WriterPriorityMutex&) = delete;
  WriterPriorityMutex& operator=(const WriterPriorityMutex&) = delete;

  void lock() {
    std::unique_lock lock(mutex_);
    ++writers_waiting_;
    writer_gone_.wait(lock, [&] { return !writer_ && readers_ == 0; });
    --writers_waiting_;
    writer_ = true;
  }
  bool try_lock() {
    std::lock_guard lock(mutex_);
    if (writer_ || readers_ > 0) return false;
    writer_ = true;
    return true;
  }
  void unlock() {
    {
      std::lock_guard lock(mutex_);
      writer_ = false;
    }
    writer_gone_.notify_all();
  }

  void lock_shared() {
    std::unique_lock lock(mutex_);
    writer_gone_.wait(lock, [&] { return !writer_ && writers_waiting_ == 0; });
    ++readers_;
  }
  bool try_lock_shared() {
    std::lock_guard lock(mutex_);
    if (writer_ || writers_waiting_ > 0) return false;
    ++readers_;
    return true;
  }
  // As lock_shared(), giving up at `deadline` (false: not taken).
  template <class Clock, class Duration>
  bool try_lock_shared_until(const std::chrono::time_point<Clock, Duration>& deadline) {
    std::unique_lock lock(mutex_);
    if (!writer_gone_.wait_until(lock, deadline, [&] { return !writer_ && writers_waiting_ == 0; })) return false;
    ++readers_;
    return true;
  }
  template <class Rep, class Period>
  bool try_lock_shared_for(const std::chrono::duration<Rep, Period>& timeout) {
    return try_lock_shared_until(std::chrono::steady_clock::now() + timeout);
  }
  void unlock_shared() {
    bool last = false;
    {
      std::lock_guard lock(mutex_);
      last = --readers_ == 0;
    }
    if (last) writer_gone_.notify_all();
  }

 private:
  std::mutex mutex_;                     // leaf
  std::condition_variable writer_gone_;  // a writer left, or the last reader did
  std::size_t readers_ = 0, writers_waiting_ = 0;
  bool writer_ = false;
};

}  // namespace orbatlas
