#pragma once
// The 8-bit grey view of an input image, as the front ends take it.
#include <opencv2/core/mat.hpp>

namespace orbatlas {

// `image` itself when it is 8-bit grey; 3- or 4-channel 8-bit images are
// converted into `scratch`. DataError (naming `which`) for an empty image, a
// depth other than 8 bits or another channel count.
const cv::Mat& as_gray(const cv::Mat& image, cv::Mat& scratch, const char* which);

}  // namespace orbatlas
