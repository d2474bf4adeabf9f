#include "server/http/imu_batch.h"

#include <algorithm>
#include <cstdint>

#include <nlohmann/json.hpp>

#include "core/common/error.h"
#include "core/common/timestamp.h"
#include "core/server/service_error.h"

namespace orbatlas {

std::vector<ImuSample> parse_imu_batch(const std::string& text) {
  using json = nlohmann::json;
  // Bounded before it is parsed (a parsed JSON array takes about ten times its text).
  if (text.size() > kMaxImuBatchBytes)
    throw ServiceError(ServiceErrorKind::kTooLarge, "too_large",
                       "an IMU batch is at most " + std::to_string(kMaxImuBatchBytes >> 20) + " MiB (" +
                           std::to_string(kMaxImuBatch) + " samples); send them in several");
  if (text.empty()) throw_bad_request("the request needs a JSON body");
  const json body = json::parse(text);  // json::exception: 400
  if (!body.is_object()) throw_bad_request("the JSON body must be an object");
  if (!body.contains("samples") || !body["samples"].is_array())
    throw_bad_request("'samples' must be an array of [t_ns, gx, gy, gz, ax, ay, az]");
  const json& rows = body["samples"];
  if (rows.size() > kMaxImuBatch)
    throw ServiceError(ServiceErrorKind::kTooLarge, "too_large",
                       "an IMU batch is at most " + std::to_string(kMaxImuBatch) + " samples, this one has " +
                           std::to_string(rows.size()));
  std::vector<ImuSample> samples;
  samples.reserve(rows.size());
  for (const json& row : rows) {
    if (!row.is_array() || row.size() != 7 || !row[0].is_number_integer() ||
        !std::all_of(row.begin() + 1, row.end(), [](const json& v) { return v.is_number(); }))
      throw_bad_request("each IMU sample is [t_ns (integer), gx, gy, gz (rad/s), ax, ay, az (m/s^2)]");
    // An integer above INT64_MAX would wrap around into a negative time.
    if (row[0].is_number_unsigned() && row[0].get<std::uint64_t>() > static_cast<std::uint64_t>(kMaxTimestampNs))
      throw DataError("IMU sample t_ns " + row[0].dump() + " is outside 0.." + std::to_string(kMaxTimestampNs));
    ImuSample s;
    s.t_ns = row[0].get<TimestampNs>();
    for (int k = 0; k < 3; ++k) {
      s.gyro[k] = row[1 + k].get<double>();
      s.accel[k] = row[4 + k].get<double>();
    }
    samples.push_back(s);
  }
  return samples;
}

}  // namespace orbatlas
