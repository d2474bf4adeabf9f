#include "core/features/descriptor.h"

#include <cstring>

#include "core/common/error.h"

namespace orbatlas {

static_assert(sizeof(Descriptor) == 32, "a descriptor is 32 bytes, as an OpenCV ORB row");

// Bytes are copied as they are (byte i of the row is byte i of the array), so a
// round trip is exact on any host and bit k of OpenCV's row is bit k here.
std::vector<Descriptor> descriptors_from_mat(const cv::Mat& rows) {
  std::vector<Descriptor> out;
  if (rows.empty()) return out;
  ORBATLAS_CHECK(rows.type() == CV_8UC1 && rows.cols == 32,
                 "ORB descriptors must be a CV_8UC1 matrix of 32 columns, got type " << rows.type() << " with "
                                                                                     << rows.cols << " columns");
  out.resize(static_cast<std::size_t>(rows.rows));
  for (int r = 0; r < rows.rows; ++r) std::memcpy(out[static_cast<std::size_t>(r)].data(), rows.ptr(r), 32);
  return out;
}

cv::Mat descriptors_to_mat(const std::vector<Descriptor>& descriptors) {
  cv::Mat rows(static_cast<int>(descriptors.size()), 32, CV_8UC1);
  for (std::size_t i = 0; i < descriptors.size(); ++i)
    std::memcpy(rows.ptr(static_cast<int>(i)), descriptors[i].data(), 32);
  return rows;
}

}  // namespace orbatlas
