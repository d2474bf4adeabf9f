#include "core/vocabulary/parallel_chunks.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace orbatlas::vocabulary_detail {

void run_chunks(std::size_t n, std::size_t chunks, int threads,
                const std::function<void(std::size_t chunk, std::size_t begin, std::size_t end)>& fn) {
  chunks = std::max<std::size_t>(1, std::min(chunks, std::max<std::size_t>(n, 1)));
  const auto slice_begin = [&](std::size_t c) { return n * c / chunks; };
  const std::size_t workers = std::min<std::size_t>(chunks, static_cast<std::size_t>(std::max(threads, 1)));
  if (workers <= 1) {
    for (std::size_t c = 0; c < chunks; ++c) fn(c, slice_begin(c), slice_begin(c + 1));
    return;
  }
  std::atomic<std::size_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  const auto work = [&]() {
    for (std::size_t c = next++; c < chunks; c = next++) {
      try {
        fn(c, slice_begin(c), slice_begin(c + 1));
      } catch (...) {
        const std::lock_guard lock(error_mutex);
        if (!error) error = std::current_exception();
        next = chunks;  // stop handing out work
      }
    }
  };
  {
    std::vector<std::jthread> pool;
    pool.reserve(workers - 1);
    for (std::size_t t = 1; t < workers; ++t) pool.emplace_back(work);
    work();
  }  // joins
  if (error) std::rethrow_exception(error);
}

}  // namespace orbatlas::vocabulary_detail
