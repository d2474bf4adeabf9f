#pragma once
// "pid N on host H": how a writer or a server replica names itself in the
// database (atlas_writer.holder, replicas.holder) and in refusals.
#include <unistd.h>

#include <climits>
#include <string>

namespace orbatlas {

inline std::string process_holder() {
  char host[HOST_NAME_MAX + 1] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return "pid " + std::to_string(::getpid()) + " on host " + (host[0] ? host : "?");
}

}  // namespace orbatlas
