#pragma once
// The body of `POST /v1/sessions/{id}/imu` (docs/api.md): {"samples": [[t_ns,
// gx, gy, gz, ax, ay, az], ...]}, bounded before it is parsed. No HTTP here,
// so the parser can be fuzzed alone (fuzz/fuzz_imu_batch.cc).
#include <cstddef>
#include <string>
#include <vector>

#include "core/io/euroc_types.h"

namespace orbatlas {

// One batch: 100 s of a 200 Hz IMU, in at most 4 MiB of JSON.
constexpr std::size_t kMaxImuBatch = 20000;
constexpr std::size_t kMaxImuBatchBytes = 4u << 20;

// ServiceError (400 bad_request, 413 too_large), DataError (422: a time past
// the timestamps' range) or nlohmann::json::exception (400 bad_json). The
// values' and times' order are the session's to check (LiveSession::add_imu).
std::vector<ImuSample> parse_imu_batch(const std::string& body);

}  // namespace orbatlas
