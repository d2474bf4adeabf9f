#pragma once
// The CPU share of background threads: the map server's local
// mapping, loop closing, global BA, map merging and checkpoints run at a
// higher nice value than the sessions' tracking, so that on a loaded machine
// the kernel's scheduler gives the frames waiting for an answer the cores
// first and the background work the rest (Linux: nice is per thread).
namespace orbatlas {

// Sets the calling thread's nice value (0 .. 19; 0 leaves the thread as it
// is). A failure (a value the system refuses) is logged once per call and
// ignored: priority is an optimisation, never a reason to stop.
void set_current_thread_nice(int nice);

// The calling thread's nice value (for tests).
int current_thread_nice();

}  // namespace orbatlas
