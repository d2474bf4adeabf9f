#include "core/common/serial_worker.h"

#include "core/common/log.h"
#include "core/common/thread_name.h"
#include "core/common/thread_priority.h"

namespace orbatlas {

SerialWorker::SerialWorker(std::size_t capacity, int nice, std::string name) : queue_(capacity) {
  thread_ = std::thread([this, nice, name = std::move(name)] {
    set_current_thread_nice(nice);
    if (!name.empty()) set_current_thread_name(name);
    while (auto task = queue_.pop()) {
      try {
        (*task)();
      } catch (const std::exception& e) {
        log_warn(std::string("a background task failed: ") + e.what());
      }
    }
  });
}

SerialWorker::~SerialWorker() { stop(); }

bool SerialWorker::try_post(std::function<void()> task) { return queue_.try_push(std::move(task)); }

void SerialWorker::stop() {
  queue_.close();
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

}  // namespace orbatlas
