#include "core/server/image_decode.h"

#include <cstring>
#include <opencv2/imgcodecs.hpp>

#include "core/common/error.h"

namespace orbatlas {
namespace {

bool starts_with(std::string_view bytes, std::string_view magic) { return bytes.substr(0, magic.size()) == magic; }

bool looks_encoded(std::string_view bytes) {
  return starts_with(bytes, "\x89PNG\r\n\x1a\n") || starts_with(bytes, "\xff\xd8\xff") || starts_with(bytes, "P5") ||
         starts_with(bytes, "BM");
}

}  // namespace

cv::Mat decode_request_image(std::string_view bytes, const std::optional<RawImageSize>& raw, const std::string& what) {
  ORBATLAS_DATA_CHECK(!bytes.empty(), what << " is empty");
  // Raw pixels when the size says so: their first bytes may look like a file signature.
  const bool raw_sized = raw && raw->width > 0 && raw->height > 0 &&
                         bytes.size() == static_cast<std::size_t>(raw->width) * static_cast<std::size_t>(raw->height);
  if (!raw_sized && looks_encoded(bytes)) {
    const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
    cv::Mat image;
    try {
      image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception&) {
      image.release();
    }
    ORBATLAS_DATA_CHECK(!image.empty(), what << " is a corrupt or truncated image file (" << bytes.size() << " bytes)");
    ORBATLAS_DATA_CHECK(image.depth() == CV_8U, what << " must have 8-bit pixels (it has " << (image.elemSize1() * 8)
                                                     << "-bit ones)");
    return image;
  }
  ORBATLAS_DATA_CHECK(raw.has_value(), what << " is not a PNG/JPEG/PGM file; raw 8-bit pixels need the fields "
                                               "'width' and 'height'");
  ORBATLAS_DATA_CHECK(raw->width > 0 && raw->height > 0 && raw->width <= 16384 && raw->height <= 16384,
                      what << ": width and height must be 1..16384, got " << raw->width << "x" << raw->height);
  const auto expected = static_cast<std::size_t>(raw->width) * static_cast<std::size_t>(raw->height);
  ORBATLAS_DATA_CHECK(bytes.size() == expected, what << " has " << bytes.size() << " bytes; " << raw->width << "x"
                                                     << raw->height << " raw 8-bit pixels are " << expected);
  cv::Mat image(raw->height, raw->width, CV_8UC1);
  std::memcpy(image.data, bytes.data(), expected);
  return image;
}

}  // namespace orbatlas
