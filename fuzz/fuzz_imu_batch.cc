// libFuzzer: the IMU batch body (server/http/imu_batch.h). Every input is
// either samples or one of the documented errors; nothing else escapes.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "core/common/error.h"
#include "server/http/imu_batch.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto samples = orbatlas::parse_imu_batch(std::string(reinterpret_cast<const char*>(data), size));
    if (samples.size() > orbatlas::kMaxImuBatch) __builtin_trap();
  } catch (const orbatlas::Error&) {
  } catch (const nlohmann::json::exception&) {
  }
  return 0;
}
