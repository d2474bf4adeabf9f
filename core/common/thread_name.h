#pragma once
// Names for the map server's threads, so that `top -H`, `ps -L`, perf and
// /proc/<pid>/task/<tid>/comm tell tracking (the HTTP threads, which keep the
// process's name) from local mapping, loop closing, global BA, map merging,
// checkpoints and uploads; scripts/bench/capacity.sh reports CPU by these names.
#include <string>
#include <string_view>

namespace orbatlas {

// Names the calling thread (Linux keeps the first 15 bytes). A failure is
// ignored: a name is for people and tools, never a reason to stop.
void set_current_thread_name(std::string_view name);

// The calling thread's name (for tests).
std::string current_thread_name();

}  // namespace orbatlas
