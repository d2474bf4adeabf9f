#include "core/common/process_memory.h"

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

}  // namespace orbatlas
