// SerialWorker: tasks run in order on one thread; a full queue or a stopped
// worker refuses a task; stop() runs what was queued before it returns.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include "core/common/serial_worker.h"

namespace orbatlas {
namespace {

TEST(SerialWorker, RunsTasksInOrderRefusesWhenFullAndDrainsOnStop) {
  SerialWorker worker(2);
  std::promise<void> release;
  std::shared_future<void> gate = release.get_future().share();
  std::mutex mutex;
  std::vector<int> order;
  std::thread::id worker_thread;
  // The first task blocks the thread, so the queue fills up behind it.
  std::promise<void> started;
  ASSERT_TRUE(worker.try_post([&] {
    worker_thread = std::this_thread::get_id();
    started.set_value();
    gate.wait();
  }));
  started.get_future().wait();
  for (int i = 0; i < 2; ++i)
    ASSERT_TRUE(worker.try_post([&, i] {
      std::lock_guard lock(mutex);
      order.push_back(i);
      EXPECT_EQ(std::this_thread::get_id(), worker_thread);
    }));
  EXPECT_FALSE(worker.try_post([] {}));  // full: refused, not blocked
  EXPECT_EQ(worker.queued(), 2u);
  // A throwing task does not stop the worker.
  release.set_value();
  while (worker.queued() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_TRUE(worker.try_post([] { throw std::runtime_error("a failing task"); }));
  EXPECT_TRUE(worker.try_post([&] {
    std::lock_guard lock(mutex);
    order.push_back(2);
  }));
  worker.stop();  // drains
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2}));
  EXPECT_FALSE(worker.try_post([] {}));  // stopped
  worker.stop();                         // idempotent
}

}  // namespace
}  // namespace orbatlas
