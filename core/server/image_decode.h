#pragma once
// Images in API requests: an encoded file (PNG, JPEG, PGM: whatever OpenCV
// decodes) or raw 8-bit grey pixels with their width and height. Throws
// DataError naming `what` ("left image") on anything else. With a raw size whose
// pixel count matches the bytes, the bytes are pixels (whatever they begin with).
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <string_view>

namespace orbatlas {

struct RawImageSize {
  int width = 0, height = 0;
};

cv::Mat decode_request_image(std::string_view bytes, const std::optional<RawImageSize>& raw, const std::string& what);

}  // namespace orbatlas
