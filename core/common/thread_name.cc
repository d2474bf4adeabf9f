#include "core/common/thread_name.h"

#include <pthread.h>

namespace orbatlas {

void set_current_thread_name(std::string_view name) {
  // pthread_setname_np refuses names of 16 bytes or more (with the terminator).
  const std::string kept(name.substr(0, 15));
  ::pthread_setname_np(::pthread_self(), kept.c_str());
}

std::string current_thread_name() {
  char name[16] = {};
  if (::pthread_getname_np(::pthread_self(), name, sizeof(name)) != 0) return {};
  return name;
}

}  // namespace orbatlas
