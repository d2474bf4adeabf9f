// QueueWorker, the block every background worker is built on: items run in
// order on one thread, failures are counted and become fatal after a run of
// them, pause() holds processing between items, finish() drains and stop()
// discards, and on a shared thread finish() waits for the worker's own items.
#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/common/queue_worker.h"
#include "core/common/thread_name.h"
#include "core/common/thread_priority.h"

namespace orbatlas {
namespace {

std::string describe(const int& item) { return "item " + std::to_string(item); }

QueueWorkerOptions options(std::size_t capacity, std::size_t fatal_after = 20,
                           std::shared_ptr<SerialWorker> shared = nullptr) {
  QueueWorkerOptions o;
  o.name = "test";
  o.capacity = capacity;
  o.fatal_after = fatal_after;
  o.shared = std::move(shared);
  return o;
}

// Blocks the worker until release() (so the queue can be filled behind it).
class Gate {
 public:
  void wait_inside() {
    entered_.set_value();
    open_.wait();
  }
  void wait_entered() { entered_future_.wait(); }
  void release() { release_.set_value(); }

 private:
  std::promise<void> entered_;
  std::future<void> entered_future_ = entered_.get_future();
  std::promise<void> release_;
  std::shared_future<void> open_ = release_.get_future().share();
};

TEST(QueueWorker, RunsItemsInOrderOnOneThreadAndReportsIdle) {
  std::mutex mutex;
  std::vector<int> seen;
  std::vector<std::thread::id> threads;
  QueueWorker<int> worker(
      options(4),
      [&](int& item) {
        std::lock_guard lock(mutex);
        seen.push_back(item);
        threads.push_back(std::this_thread::get_id());
      },
      describe);
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(worker.push(i));
  worker.wait_until_idle();
  EXPECT_TRUE(worker.idle());
  EXPECT_EQ(worker.in_flight(), 0u);
  std::vector<int> expected(20);
  for (int i = 0; i < 20; ++i) expected[i] = i;
  EXPECT_EQ(seen, expected);
  for (const auto& id : threads) EXPECT_EQ(id, threads.front());
  EXPECT_NE(threads.front(), std::this_thread::get_id());
  worker.finish();
  EXPECT_FALSE(worker.push(99));  // finished: refused
  EXPECT_FALSE(worker.try_push(99));
}

// Background workers run at the nice value they are given (the map server's
// mapping below its tracking); the thread that created them keeps its own.
TEST(QueueWorker, AWorkersThreadRunsAtItsNiceValue) {
  const int own = current_thread_nice();
  std::atomic<int> seen{-100};
  {
    QueueWorker<int> worker(
        QueueWorkerOptions::own_thread("nice", 4, 20, 7), [&](int&) { seen.store(current_thread_nice()); },
        [](const int& i) { return std::to_string(i); });
    worker.push(1);
    worker.wait_until_idle();
  }
  // Raising a thread's nice value always works; lowering it below the
  // creator's (when the tests themselves run niced) may need privileges.
  if (own <= 7) {
    EXPECT_EQ(seen.load(), 7);
  }
  EXPECT_GE(seen.load(), 7);
  EXPECT_EQ(current_thread_nice(), own);
  SerialWorker serial(2, 3);
  std::atomic<int> serial_seen{-100};
  std::promise<void> done;
  ASSERT_TRUE(serial.try_post([&] {
    serial_seen.store(current_thread_nice());
    done.set_value();
  }));
  done.get_future().wait();
  if (own <= 3) {
    EXPECT_EQ(serial_seen.load(), 3);
  }
  EXPECT_GE(serial_seen.load(), 3);
}

// Background threads carry their worker's name (thread_name.h: `top -H`, perf,
// and the capacity benchmark's CPU by thread); names longer than Linux keeps
// are cut at 15 bytes; the creating thread keeps its own.
TEST(QueueWorker, AWorkersThreadCarriesItsName) {
  const std::string own = current_thread_name();
  std::string seen;
  {
    QueueWorker<int> worker(
        QueueWorkerOptions::own_thread("local mapping", 4), [&](int&) { seen = current_thread_name(); },
        [](const int& i) { return std::to_string(i); });
    worker.push(1);
    worker.wait_until_idle();
    EXPECT_EQ(seen, "local mapping");
  }
  std::string serial_seen;
  std::promise<void> done;
  SerialWorker serial(2, 0, "a name longer than fifteen bytes");
  ASSERT_TRUE(serial.try_post([&] {
    serial_seen = current_thread_name();
    done.set_value();
  }));
  done.get_future().wait();
  EXPECT_EQ(serial_seen, "a name longer t");
  EXPECT_EQ(current_thread_name(), own);
}

TEST(QueueWorker, TryPushRefusesWhenFullWithoutBlocking) {
  Gate gate;
  QueueWorker<int> worker(
      options(2),
      [&](int& item) {
        if (item == 0) gate.wait_inside();
      },
      describe);
  ASSERT_TRUE(worker.try_push(0));
  gate.wait_entered();
  EXPECT_TRUE(worker.try_push(1));
  EXPECT_TRUE(worker.try_push(2));
  EXPECT_FALSE(worker.try_push(3));  // full
  EXPECT_EQ(worker.queued(), 2u);
  EXPECT_EQ(worker.in_flight(), 3u);  // the refused one is not counted
  gate.release();
  worker.wait_until_idle();
}

TEST(QueueWorker, AFailedItemIsCountedAndARunOfFailuresIsFatal) {
  QueueWorker<int> worker(
      options(8, 3),
      [](int& item) {
        if (item < 0) throw std::runtime_error("bad item " + std::to_string(item));
      },
      describe);
  ASSERT_TRUE(worker.push(-1));
  ASSERT_TRUE(worker.push(1));  // resets the run
  ASSERT_TRUE(worker.push(-2));
  worker.wait_until_idle();  // two failures, not in a row: not fatal
  EXPECT_EQ(worker.errors().errors, 2u);
  EXPECT_NE(worker.errors().last.find("bad item -2"), std::string::npos);
  EXPECT_FALSE(worker.errors().fatal);
  // A success ends the run of -2, so the run of three failures ends with the
  // last item pushed: no push can meet the fatal error (the worker may take
  // each item as soon as it is pushed).
  ASSERT_TRUE(worker.push(2));
  for (int i = 3; i <= 5; ++i) ASSERT_TRUE(worker.push(-i));
  EXPECT_THROW(worker.wait_until_idle(), WorkerFailed);
  EXPECT_TRUE(worker.errors().fatal);
  EXPECT_THROW(worker.push(7), WorkerFailed);  // the feeding session learns of it
  EXPECT_THROW(worker.finish(), WorkerFailed);
  EXPECT_NO_THROW(worker.finish());  // raised once
}

TEST(QueueWorker, NeverFatalKeepsGoing) {
  int done = 0;
  QueueWorker<int> worker(
      options(8, QueueWorkerOptions::kNeverFatal),
      [&](int& item) {
        if (item < 0) throw std::runtime_error("bad");
        ++done;
      },
      describe);
  for (int i = 0; i < 30; ++i) ASSERT_TRUE(worker.push(-1));
  ASSERT_TRUE(worker.push(1));
  EXPECT_NO_THROW(worker.wait_until_idle());
  EXPECT_EQ(done, 1);
  EXPECT_EQ(worker.errors().errors, 30u);
}

TEST(QueueWorker, PauseProcessesWhatIsQueuedThenHoldsUntilResume) {
  std::mutex mutex;
  std::vector<int> seen;
  Gate gate;
  QueueWorker<int> worker(
      options(8),
      [&](int& item) {
        if (item == 0) gate.wait_inside();
        std::lock_guard lock(mutex);
        seen.push_back(item);
      },
      describe);
  ASSERT_TRUE(worker.push(0));
  ASSERT_TRUE(worker.push(1));
  gate.wait_entered();
  auto paused = std::async(std::launch::async, [&] { worker.pause(); });
  while (!worker.pause_requested()) std::this_thread::yield();
  EXPECT_EQ(paused.wait_for(std::chrono::milliseconds(20)), std::future_status::timeout);  // item 0 runs
  gate.release();
  paused.get();  // returns once 0 and 1 are done
  {
    std::lock_guard lock(mutex);
    EXPECT_EQ(seen, (std::vector<int>{0, 1}));
  }
  ASSERT_TRUE(worker.push(2));  // handed in while paused: waits
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  {
    std::lock_guard lock(mutex);
    EXPECT_EQ(seen.size(), 2u);
  }
  worker.resume();
  EXPECT_FALSE(worker.pause_requested());
  worker.wait_until_idle();
  EXPECT_EQ(seen, (std::vector<int>{0, 1, 2}));
}

TEST(QueueWorker, StopDiscardsWhatIsQueuedFinishDrainsIt) {
  for (const bool discard : {false, true}) {
    Gate gate;
    int done = 0;
    QueueWorker<int> worker(
        options(8),
        [&](int& item) {
          if (item == 0) gate.wait_inside();
          ++done;
        },
        describe);
    for (int i = 0; i < 4; ++i) ASSERT_TRUE(worker.push(i));
    gate.wait_entered();
    auto stopped = std::async(std::launch::async, [&] { discard ? worker.stop() : worker.finish(); });
    int accepted = 0;  // pushed before stopping began
    while (worker.try_push(9)) ++accepted;
    while (worker.push(9)) ++accepted;  // refused once stopping began
    gate.release();
    stopped.get();
    EXPECT_EQ(done, discard ? 1 : 4 + accepted) << (discard ? "stop" : "finish");
    EXPECT_EQ(worker.discarded(), discard ? 3u + accepted : 0u);
    EXPECT_EQ(worker.in_flight(), 0u);
  }
}

TEST(QueueWorker, OnASharedThreadFinishWaitsForItsOwnItems) {
  auto shared = std::make_shared<SerialWorker>(16);
  std::mutex mutex;
  std::vector<int> seen;
  std::thread::id thread_a, thread_b;
  Gate gate;
  QueueWorker<int> a(
      options(4, 20, shared),
      [&](int& item) {
        if (item == 0) gate.wait_inside();
        std::lock_guard lock(mutex);
        thread_a = std::this_thread::get_id();
        seen.push_back(item);
      },
      describe);
  QueueWorker<int> b(
      options(4, 20, shared),
      [&](int& item) {
        std::lock_guard lock(mutex);
        thread_b = std::this_thread::get_id();
        seen.push_back(100 + item);
      },
      describe);
  ASSERT_TRUE(a.push(0));
  gate.wait_entered();
  ASSERT_TRUE(b.push(1));
  ASSERT_TRUE(a.push(2));
  EXPECT_EQ(a.queued(), 2u);       // the shared thread's queue
  EXPECT_THROW(a.pause(), Error);  // would hold up b
  auto finished = std::async(std::launch::async, [&] { a.finish(); });
  EXPECT_EQ(finished.wait_for(std::chrono::milliseconds(20)), std::future_status::timeout);
  gate.release();
  finished.get();
  {
    std::lock_guard lock(mutex);
    EXPECT_EQ(seen, (std::vector<int>{0, 101, 2}));  // in order of posting, on one thread
  }
  b.finish();
  EXPECT_EQ(thread_a, thread_b);
}

}  // namespace
}  // namespace orbatlas
