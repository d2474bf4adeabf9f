#include "core/persistence/inertial_blob.h"

#include <cmath>

#include "core/common/error.h"
#include "core/persistence/blob_codec.h"

namespace orbatlas {
namespace {

// Version 1: version, bias (6), densities (4); version 2 adds the vibration's
// variances (rotation 3, velocity 3).
constexpr std::size_t kHeaderV1 = 11, kHeader = 17, kPerMeasurement = 7;

}  // namespace

std::string encode_increments(const Preintegration& increments) {
  std::vector<double> v;
  v.reserve(kHeader + kPerMeasurement * increments.measurements().size());
  const ImuBias& b = increments.bias();
  const ImuNoise& n = increments.noise();
  v.push_back(kIncrementsBlobVersion);
  for (int i = 0; i < 3; ++i) v.push_back(b.gyro[i]);
  for (int i = 0; i < 3; ++i) v.push_back(b.accel[i]);
  v.insert(v.end(), {n.gyro_density, n.accel_density, n.gyro_walk, n.accel_walk});
  for (int i = 0; i < 3; ++i) v.push_back(n.vibration.rotation_var[i]);
  for (int i = 0; i < 3; ++i) v.push_back(n.vibration.velocity_var[i]);
  for (const Preintegration::Measurement& m : increments.measurements()) {
    for (int i = 0; i < 3; ++i) v.push_back(m.gyro[i]);
    for (int i = 0; i < 3; ++i) v.push_back(m.accel[i]);
    v.push_back(m.dt);
  }
  return encode_doubles(v);
}

Preintegration decode_increments(std::string_view blob, const std::string& what) {
  const std::vector<double> v = decode_doubles(blob, what);
  ORBATLAS_DATA_CHECK(!v.empty() && (v[0] == 1.0 || v[0] == kIncrementsBlobVersion),
                      what << ": inertial increments of an unknown version (this build reads versions 1 and 2)");
  const std::size_t header = v[0] == 1.0 ? kHeaderV1 : kHeader;
  ORBATLAS_DATA_CHECK(
      v.size() >= header && (v.size() - header) % kPerMeasurement == 0,
      what << ": inertial increments of " << v.size() << " values (" << header << " + 7 per measurement)");
  for (const double x : v) ORBATLAS_DATA_CHECK(std::isfinite(x), what << ": inertial increments not finite");
  ImuBias bias;
  bias.gyro = {v[1], v[2], v[3]};
  bias.accel = {v[4], v[5], v[6]};
  ImuNoise noise;
  noise.gyro_density = v[7];
  noise.accel_density = v[8];
  noise.gyro_walk = v[9];
  noise.accel_walk = v[10];
  ORBATLAS_DATA_CHECK(
      noise.gyro_density > 0.0 && noise.accel_density > 0.0 && noise.gyro_walk > 0.0 && noise.accel_walk > 0.0,
      what << ": inertial increments with a noise density <= 0");
  if (header == kHeader) {
    noise.vibration.rotation_var = {v[11], v[12], v[13]};
    noise.vibration.velocity_var = {v[14], v[15], v[16]};
    ORBATLAS_DATA_CHECK(
        noise.vibration.rotation_var.minCoeff() >= 0.0 && noise.vibration.velocity_var.minCoeff() >= 0.0,
        what << ": inertial increments with a vibration variance < 0");
  }
  Preintegration out(bias, noise);
  for (std::size_t i = header; i < v.size(); i += kPerMeasurement) {
    ORBATLAS_DATA_CHECK(v[i + 6] > 0.0, what << ": an inertial measurement held for dt <= 0");
    out.integrate({v[i], v[i + 1], v[i + 2]}, {v[i + 3], v[i + 4], v[i + 5]}, v[i + 6]);
  }
  return out;
}

}  // namespace orbatlas
