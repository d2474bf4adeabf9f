#pragma once
// Memory of this process as the kernel accounts it (Linux /proc/self/status).
namespace orbatlas {

double peak_rss_mb();     // VmHWM; 0 when unavailable
double current_rss_mb();  // VmRSS; 0 when unavailable
// Bytes the program holds from the C heap now (glibc mallinfo2: in use, not
// what the allocator keeps for reuse). RSS minus this is the allocator's share.
double heap_in_use_mb();
// Gives memory the allocator keeps but nobody uses back to the kernel
// (glibc malloc_trim); a long-running server calls it when a session ends.
void release_free_heap();

}  // namespace orbatlas
