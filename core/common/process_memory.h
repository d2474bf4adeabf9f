#pragma once
// Memory of this process as the kernel accounts it (Linux /proc/self/status).
namespace orbatlas {

double peak_rss_mb();     // VmHWM; 0 when unavailable
double current_rss_mb();  // VmRSS; 0 when unavailable

}  // namespace orbatlas
