#pragma once
// The binary blobs of the atlas database (layouts in docs/schema.md):
//  - a keyframe's features: Cereal binary with a leading u32 version tag;
//  - a map point's descriptor: the 32 raw bytes of the 256-bit descriptor;
//  - a camera's distortion coefficients: a raw float64 array.
// Decoding never trusts the blob: an unknown version, a truncated blob, trailing
// bytes or inconsistent counts throw DataError naming `what` (e.g. "keyframe 12").
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/features/descriptor.h"
#include "core/features/keypoint.h"

namespace orbatlas {

// Version of the features blob this build writes (and the only one it reads).
inline constexpr std::uint32_t kFeaturesBlobVersion = 1;

// The stored part of a keyframe's immutable data (KeyFrameData without poses,
// bag of words and grid, which are columns or recomputed).
struct StoredFeatures {
  ImageFeatures features;      // keypoints (every field), descriptors, image size
  std::vector<float> depth;    // empty (monocular) or one per keypoint
  std::vector<float> u_right;  // same size as depth
};

// Throws Error when the descriptor or stereo vectors are neither empty nor one per keypoint.
std::string encode_features(const ImageFeatures& features, const std::vector<float>& depth,
                            const std::vector<float>& u_right);
StoredFeatures decode_features(std::string_view blob, const std::string& what);

std::string encode_descriptor(const Descriptor& descriptor);
Descriptor decode_descriptor(std::string_view blob, const std::string& what);

std::string encode_doubles(const std::vector<double>& values);
std::vector<double> decode_doubles(std::string_view blob, const std::string& what);

}  // namespace orbatlas
