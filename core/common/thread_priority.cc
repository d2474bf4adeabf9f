#include "core/common/thread_priority.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "core/common/log.h"

namespace orbatlas {
namespace {

id_t current_thread_id() { return static_cast<id_t>(::syscall(SYS_gettid)); }

}  // namespace

void set_current_thread_nice(int nice) {
  if (nice == 0) return;
  if (::setpriority(PRIO_PROCESS, current_thread_id(), nice) != 0)
    log_warn("cannot set a background thread's nice value to " + std::to_string(nice) + ": " + std::strerror(errno));
}

int current_thread_nice() {
  errno = 0;
  return ::getpriority(PRIO_PROCESS, current_thread_id());
}

}  // namespace orbatlas
