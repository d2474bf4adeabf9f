#pragma once
// A live session's frame as one application/octet-stream body (docs/api.md
// "Frames"): the query says `t_ns`, `width` and `height`; the body is the left
// image's 8-bit grey pixels, row by row, then the right image's (a stereo
// session; a single camera sends the left image alone). No multipart parsing
// and no image decoding on the server: what a client on the same host or a fast
// link sends at the sensor's rate (orbatlas stream's default).
#include <opencv2/core/mat.hpp>

#include "core/common/timestamp.h"

namespace httplib {
struct Request;
}

namespace orbatlas {

struct RawFrame {
  TimestampNs t_ns = 0;
  cv::Mat left, right;  // right: empty when the body holds one image
};

// True when the request's Content-Type is application/octet-stream.
bool is_raw_frame_request(const httplib::Request& req);

// Throws ServiceError kBadRequest (400) for a missing or malformed query value,
// DataError (422) when the body is not one or two images of `expected` (the
// session's camera), or two where the session takes one (`stereo` false).
RawFrame parse_raw_frame(const httplib::Request& req, const cv::Size& expected, bool stereo);

}  // namespace orbatlas
