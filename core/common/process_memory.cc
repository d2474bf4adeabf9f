#include "core/common/process_memory.h"

#include <malloc.h>

#include <fstream>
#include <sstream>
#include <string>

namespace orbatlas {
namespace {

double status_kb(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key + ":", 0) != 0) continue;
    std::istringstream fields(line.substr(key.size() + 1));
    double kb = 0.0;
    fields >> kb;
    return kb;
  }
  return 0.0;
}

}  // namespace

double peak_rss_mb() { return status_kb("VmHWM") / 1024.0; }
double current_rss_mb() { return status_kb("VmRSS") / 1024.0; }

double heap_in_use_mb() {
  const struct mallinfo2 info = mallinfo2();
  return static_cast<double>(info.uordblks + info.hblkhd) / (1024.0 * 1024.0);
}

void release_free_heap() { malloc_trim(0); }

}  // namespace orbatlas
