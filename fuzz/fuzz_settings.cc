// libFuzzer: the settings parser on a session's inline settings_yaml
// (core/io/settings.h, OpenCV's FileStorage underneath). Errors are Error or
// cv::Exception turned into Error; nothing else escapes, nothing crashes.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/common/error.h"
#include "core/io/settings.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    orbatlas::read_settings_text(std::string(reinterpret_cast<const char*>(data), size), "fuzz");
  } catch (const orbatlas::Error&) {
  }
  return 0;
}
