// libFuzzer: images in requests (server/http/image_decode.h): the header
// sniffing that refuses a size before decoding, then OpenCV's decoders, for a
// session's 752x480 camera. The first input byte picks raw or encoded.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>

#include "core/common/error.h"
#include "server/http/image_decode.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    std::optional<orbatlas::RawImageSize> raw;
    if (data[0] & 1) raw = orbatlas::RawImageSize{1 + (data[0] >> 1), 3};
    const cv::Mat image = orbatlas::decode_request_image(bytes, raw, "fuzz image", cv::Size(752, 480));
    if (!raw && (image.cols != 752 || image.rows != 480)) __builtin_trap();  // the size was checked
    if (data[0] & 2) orbatlas::decode_request_depth(bytes, "fuzz depth", cv::Size(64, 48));
  } catch (const orbatlas::Error&) {
  }
  return 0;
}
