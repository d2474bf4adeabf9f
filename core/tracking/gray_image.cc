#include "core/tracking/gray_image.h"

#include <opencv2/imgproc.hpp>

#include "core/common/error.h"

namespace orbatlas {

const cv::Mat& as_gray(const cv::Mat& image, cv::Mat& scratch, const char* which) {
  ORBATLAS_DATA_CHECK(!image.empty(), which << " image is empty");
  ORBATLAS_DATA_CHECK(image.depth() == CV_8U, which << " image must be 8-bit");
  if (image.channels() == 1) return image;
  ORBATLAS_DATA_CHECK(image.channels() == 3 || image.channels() == 4,
                      which << " image has " << image.channels() << " channels");
  cv::cvtColor(image, scratch, image.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
  return scratch;
}

}  // namespace orbatlas
