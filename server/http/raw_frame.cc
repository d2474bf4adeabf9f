#include "server/http/raw_frame.h"

#include <cstring>
#include <string>

#include "core/common/error.h"
#include "core/common/parse_integer.h"
#include "core/io/settings.h"
#include "core/server/service_error.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas {

namespace {

std::int64_t query_integer(const httplib::Request& req, const char* key) {
  if (!req.has_param(key))
    throw_bad_request(std::string("a raw frame (application/octet-stream) needs the query parameter '") + key +
                      "' (t_ns, width, height)");
  const std::string text = req.get_param_value(key);
  const auto v = parse_integer<std::int64_t>(text);
  if (!v)
    throw_bad_request(std::string("the query parameter '") + key + "' must be an integer, got '" + text.substr(0, 40) +
                      "'");
  return *v;
}

cv::Mat copy_pixels(const char* data, const cv::Size& size) {
  cv::Mat image(size, CV_8UC1);
  std::memcpy(image.data, data, static_cast<std::size_t>(size.area()));
  return image;
}

}  // namespace

bool is_raw_frame_request(const httplib::Request& req) {
  const std::string type = req.get_header_value("Content-Type");
  return type.rfind("application/octet-stream", 0) == 0;
}

RawFrame parse_raw_frame(const httplib::Request& req, const cv::Size& expected, bool stereo) {
  RawFrame frame;
  frame.t_ns = query_integer(req, "t_ns");
  const std::int64_t width = query_integer(req, "width"), height = query_integer(req, "height");
  if (width <= 0 || height <= 0 || width > kMaxImageSide || height > kMaxImageSide)
    throw_bad_request("'width' and 'height' must be 1.." + std::to_string(kMaxImageSide) + ", got " +
                      std::to_string(width) + " and " + std::to_string(height));
  const cv::Size size(static_cast<int>(width), static_cast<int>(height));
  ORBATLAS_DATA_CHECK(size == expected, "the raw frame is " << width << "x" << height << "; the camera takes "
                                                            << expected.width << "x" << expected.height);
  const auto one = static_cast<std::size_t>(size.area());
  const std::size_t images = req.body.size() == one ? 1 : req.body.size() == 2 * one ? 2 : 0;
  ORBATLAS_DATA_CHECK(images > 0, "the raw frame's body has " << req.body.size() << " bytes; one " << width << "x"
                                                              << height << " 8-bit image is " << one
                                                              << " bytes, a stereo pair " << 2 * one);
  ORBATLAS_DATA_CHECK(images == 2 || !stereo, "this stereo session needs the left and the right image ("
                                                  << 2 * one << " bytes); the body holds one");
  ORBATLAS_DATA_CHECK(images == 1 || stereo, "this session takes one image (" << one << " bytes); the body holds two");
  frame.left = copy_pixels(req.body.data(), size);
  if (images == 2) frame.right = copy_pixels(req.body.data() + one, size);
  return frame;
}

}  // namespace orbatlas
