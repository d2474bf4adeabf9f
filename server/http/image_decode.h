#pragma once
// Images in API requests: an encoded file (PNG, JPEG, PGM, BMP) or raw 8-bit
// grey pixels with their width and height. Throws DataError naming `what`
// ("left image") on anything else. With a raw size whose pixel count matches
// the bytes, the bytes are pixels (whatever they begin with).
//
// The size an encoded file declares is read from its header before anything is
// decoded: a small file declaring a huge image (decompression amplification)
// is refused without allocating it.
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <string_view>

namespace orbatlas {

struct RawImageSize {
  int width = 0, height = 0;
};

// Width and height from a PNG, JPEG, binary PGM or BMP header; nullopt when the
// bytes are not one of these or the header is cut short.
std::optional<cv::Size> encoded_image_size(std::string_view bytes);

// `expected`: the size the session's camera takes (a different one is refused
// before decoding); without it, at most kMaxImageSide pixels a side.
cv::Mat decode_request_image(std::string_view bytes, const std::optional<RawImageSize>& raw, const std::string& what,
                             const std::optional<cv::Size>& expected = std::nullopt);

// An RGB-D frame's depth image: a 16-bit single-channel PNG (TUM RGB-D's
// format) of the `expected` size, checked from its header before decoding.
cv::Mat decode_request_depth(std::string_view bytes, const std::string& what, const cv::Size& expected);

}  // namespace orbatlas
