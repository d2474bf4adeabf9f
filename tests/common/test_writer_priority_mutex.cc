// WriterPriorityMutex: shared owners run together, a writer runs alone, and a
// writer waiting behind a stream of overlapping readers gets in (the case that
// starves a writer on a reader-preferring std::shared_mutex).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <shared_mutex>
#include <thread>
#include <vector>

#include "core/common/writer_priority_mutex.h"

namespace orbatlas {
namespace {

TEST(WriterPriorityMutex, ReadersShareAWriterIsAlone) {
  WriterPriorityMutex m;
  {
    std::shared_lock a(m);
    EXPECT_TRUE(m.try_lock_shared());  // a second reader
    m.unlock_shared();
    EXPECT_FALSE(m.try_lock());  // not while read
  }
  {
    std::unique_lock w(m);
    EXPECT_FALSE(m.try_lock_shared());
    EXPECT_FALSE(m.try_lock());
  }
  EXPECT_TRUE(m.try_lock());
  m.unlock();
}

// A shared owner with a deadline: in at once when the mutex is free, and out
// at the deadline (not before, not long after) while a writer holds it.
TEST(WriterPriorityMutex, ASharedOwnerWithADeadlineGivesUpAtIt) {
  WriterPriorityMutex m;
  EXPECT_TRUE(m.try_lock_shared_for(std::chrono::milliseconds(1)));
  m.unlock_shared();
  std::unique_lock w(m);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(m.try_lock_shared_for(std::chrono::milliseconds(30)));
  const double waited_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(waited_ms, 30.0);
  EXPECT_LT(waited_ms, 60.0);
  // Released while it waits: it gets in then.
  auto reader = std::async(std::launch::async, [&m] {
    const bool in = m.try_lock_shared_for(std::chrono::seconds(10));
    if (in) m.unlock_shared();
    return in;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  w.unlock();
  EXPECT_TRUE(reader.get());
}

TEST(WriterPriorityMutex, AWaitingWriterGetsInDespiteOverlappingReaders) {
  WriterPriorityMutex m;
  std::atomic<bool> stop{false};
  std::atomic<int> inside{0}, max_inside{0};
  std::atomic<bool> writer_saw_reader{false};
  // Four readers whose holds overlap, so that some reader holds the lock at
  // every moment: a reader-preferring lock would never let the writer in.
  std::vector<std::thread> readers;
  for (int r = 0; r < 4; ++r) {
    readers.emplace_back([&] {
      while (!stop.load()) {
        std::shared_lock lock(m);
        const int now = ++inside;
        int seen = max_inside.load();
        while (now > seen && !max_inside.compare_exchange_weak(seen, now)) {
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        --inside;
      }
    });
  }
  while (max_inside.load() < 2) std::this_thread::yield();  // readers do overlap
  auto writer = std::async(std::launch::async, [&] {
    for (int i = 0; i < 20; ++i) {
      std::unique_lock lock(m);
      if (inside.load() != 0) writer_saw_reader = true;
    }
  });
  const auto status = writer.wait_for(std::chrono::seconds(20));
  stop = true;
  for (auto& t : readers) t.join();
  ASSERT_EQ(status, std::future_status::ready) << "the writer was starved";
  writer.get();
  EXPECT_FALSE(writer_saw_reader.load());
  EXPECT_GE(max_inside.load(), 2);
}

}  // namespace
}  // namespace orbatlas
