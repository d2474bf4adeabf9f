// Blobs are written with Cereal's binary archive: fixed-size scalars and
// contiguous arrays (binary_data), in native byte order, which the build
// requires to be little-endian so that the files are portable between the
// machines we run on.
#include "core/persistence/blob_codec.h"

#include <bit>
#include <cstring>
#include <istream>
#include <sstream>
#include <streambuf>

#include <cereal/archives/binary.hpp>

#include "core/common/error.h"

namespace orbatlas {
namespace {

static_assert(std::endian::native == std::endian::little, "atlas blobs are little-endian");
static_assert(sizeof(Descriptor) == 32);

// A read-only stream over the blob that knows how many bytes are left, so array
// lengths can be checked before anything is allocated.
class BlobReader : public std::streambuf {
 public:
  explicit BlobReader(std::string_view bytes) {
    // The get area is only read; streambuf merely lacks a const interface.
    char* begin = const_cast<char*>(bytes.data());
    setg(begin, begin, begin + bytes.size());
  }
  std::size_t remaining() const { return static_cast<std::size_t>(egptr() - gptr()); }
};

class FeaturesDecoder {
 public:
  FeaturesDecoder(std::string_view blob, const std::string& what)
      : reader_(blob), in_(&reader_), ar_(in_), what_(what) {}

  template <class T>
  T scalar(const char* field) {
    need(sizeof(T), field);
    T value{};
    ar_(value);
    return value;
  }
  template <class T>
  void array(std::vector<T>& out, std::uint64_t count, const char* field) {
    if (count > reader_.remaining() / sizeof(T))
      fail(std::string("truncated: ") + field + " needs " + std::to_string(count) + " x " + std::to_string(sizeof(T)) +
           " bytes, " + std::to_string(reader_.remaining()) + " remain");
    out.resize(static_cast<std::size_t>(count));
    ar_(cereal::binary_data(out.data(), out.size() * sizeof(T)));
  }
  std::size_t remaining() const { return reader_.remaining(); }
  [[noreturn]] void fail(const std::string& message) const { throw DataError(what_ + ": features blob: " + message); }

 private:
  void need(std::size_t bytes, const char* field) {
    if (reader_.remaining() < bytes) fail(std::string("truncated before ") + field);
  }

  BlobReader reader_;
  std::istream in_;
  cereal::BinaryInputArchive ar_;
  const std::string& what_;
};

template <class T>
void write_array(cereal::BinaryOutputArchive& ar, const std::vector<T>& v) {
  if (!v.empty()) ar(cereal::binary_data(v.data(), v.size() * sizeof(T)));
}

}  // namespace

std::string encode_features(const ImageFeatures& features, const std::vector<float>& depth,
                            const std::vector<float>& u_right) {
  const std::size_t n = features.keypoints.size();
  ORBATLAS_CHECK(features.descriptors.empty() || features.descriptors.size() == n,
                 "features blob: " << features.descriptors.size() << " descriptors for " << n << " keypoints");
  ORBATLAS_CHECK((depth.empty() || depth.size() == n) && u_right.size() == depth.size(),
                 "features blob: " << depth.size() << " depths and " << u_right.size() << " right columns for " << n
                                   << " keypoints");
  // Field by field (structure of arrays): no padding, a layout that does not
  // depend on the compiler, and each array in one binary_data call.
  std::vector<float> uv(2 * n), angle(n), response(n), uv_undistorted(2 * n);
  std::vector<std::int32_t> level(n);
  std::vector<double> bearing(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Keypoint& kp = features.keypoints[i];
    uv[2 * i] = kp.uv.x();
    uv[2 * i + 1] = kp.uv.y();
    level[i] = kp.level;
    angle[i] = kp.angle_deg;
    response[i] = kp.response;
    for (int k = 0; k < 3; ++k) bearing[3 * i + static_cast<std::size_t>(k)] = kp.bearing[k];
    uv_undistorted[2 * i] = kp.uv_undistorted.x();
    uv_undistorted[2 * i + 1] = kp.uv_undistorted.y();
  }
  std::ostringstream out(std::ios::binary);
  {
    cereal::BinaryOutputArchive ar(out);
    ar(kFeaturesBlobVersion);
    ar(static_cast<std::int32_t>(features.width), static_cast<std::int32_t>(features.height));
    ar(static_cast<std::uint64_t>(n));
    write_array(ar, uv);
    write_array(ar, level);
    write_array(ar, angle);
    write_array(ar, response);
    write_array(ar, bearing);
    write_array(ar, uv_undistorted);
    ar(static_cast<std::uint64_t>(features.descriptors.size()));
    write_array(ar, features.descriptors);
    ar(static_cast<std::uint64_t>(depth.size()));
    write_array(ar, depth);
    write_array(ar, u_right);
  }
  return std::move(out).str();
}

StoredFeatures decode_features(std::string_view blob, const std::string& what) {
  FeaturesDecoder d(blob, what);
  StoredFeatures out;
  try {
    const auto version = d.scalar<std::uint32_t>("the version tag");
    if (version != kFeaturesBlobVersion)
      d.fail("unknown version " + std::to_string(version) + " (this build reads version " +
             std::to_string(kFeaturesBlobVersion) + ")");
    out.features.width = d.scalar<std::int32_t>("the image width");
    out.features.height = d.scalar<std::int32_t>("the image height");
    if (out.features.width < 0 || out.features.height < 0)
      d.fail("negative image size " + std::to_string(out.features.width) + "x" + std::to_string(out.features.height));
    const auto n = d.scalar<std::uint64_t>("the keypoint count");
    std::vector<float> uv, angle, response, uv_undistorted;
    std::vector<std::int32_t> level;
    std::vector<double> bearing;
    // The smallest possible keypoint record bounds n before anything is multiplied by it.
    constexpr std::size_t kBytesPerKeypoint = 2 * 4 + 4 + 4 + 4 + 3 * 8 + 2 * 4;
    if (n > d.remaining() / kBytesPerKeypoint)
      d.fail("truncated: " + std::to_string(n) + " keypoints announced, " + std::to_string(d.remaining()) +
             " bytes remain");
    d.array(uv, 2 * n, "keypoint positions");
    d.array(level, n, "keypoint levels");
    d.array(angle, n, "keypoint angles");
    d.array(response, n, "keypoint responses");
    d.array(bearing, 3 * n, "keypoint bearings");
    d.array(uv_undistorted, 2 * n, "undistorted keypoint positions");
    const auto n_descriptors = d.scalar<std::uint64_t>("the descriptor count");
    if (n_descriptors != 0 && n_descriptors != n)
      d.fail(std::to_string(n_descriptors) + " descriptors for " + std::to_string(n) + " keypoints");
    d.array(out.features.descriptors, n_descriptors, "descriptors");
    const auto n_stereo = d.scalar<std::uint64_t>("the stereo count");
    if (n_stereo != 0 && n_stereo != n)
      d.fail(std::to_string(n_stereo) + " depths for " + std::to_string(n) + " keypoints");
    d.array(out.depth, n_stereo, "depths");
    d.array(out.u_right, n_stereo, "right columns");
    if (d.remaining() != 0) d.fail(std::to_string(d.remaining()) + " unexpected trailing bytes");

    out.features.keypoints.resize(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < out.features.keypoints.size(); ++i) {
      Keypoint& kp = out.features.keypoints[i];
      kp.uv = {uv[2 * i], uv[2 * i + 1]};
      kp.level = level[i];
      kp.angle_deg = angle[i];
      kp.response = response[i];
      kp.bearing = {bearing[3 * i], bearing[3 * i + 1], bearing[3 * i + 2]};
      kp.uv_undistorted = {uv_undistorted[2 * i], uv_undistorted[2 * i + 1]};
    }
  } catch (const cereal::Exception& e) {  // cannot happen after the length checks; kept as a backstop
    d.fail(std::string("unreadable: ") + e.what());
  }
  return out;
}

std::string encode_descriptor(const Descriptor& descriptor) {
  std::string bytes(sizeof(Descriptor), '\0');
  std::memcpy(bytes.data(), descriptor.data(), sizeof(Descriptor));
  return bytes;
}

Descriptor decode_descriptor(std::string_view blob, const std::string& what) {
  ORBATLAS_DATA_CHECK(blob.size() == sizeof(Descriptor),
                      what << ": descriptor blob of " << blob.size() << " bytes, expected " << sizeof(Descriptor));
  Descriptor d{};
  std::memcpy(d.data(), blob.data(), sizeof(Descriptor));
  return d;
}

std::string encode_doubles(const std::vector<double>& values) {
  std::string bytes(values.size() * sizeof(double), '\0');
  if (!values.empty()) std::memcpy(bytes.data(), values.data(), bytes.size());
  return bytes;
}

std::vector<double> decode_doubles(std::string_view blob, const std::string& what) {
  ORBATLAS_DATA_CHECK(blob.size() % sizeof(double) == 0,
                      what << ": float64 array blob of " << blob.size() << " bytes (not a multiple of 8)");
  std::vector<double> values(blob.size() / sizeof(double));
  if (!values.empty()) std::memcpy(values.data(), blob.data(), blob.size());
  return values;
}

}  // namespace orbatlas
