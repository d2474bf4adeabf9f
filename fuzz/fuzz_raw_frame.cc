// libFuzzer: a raw-pixel frame (server/http/raw_frame.h): the query's t_ns,
// width and height and the body, as the route gets them. The input is the
// three query values, one per line, then the body.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/common/error.h"
#include "server/http/raw_frame.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  httplib::Request req;
  req.set_header("Content-Type", "application/octet-stream");
  std::size_t at = 0;
  for (const char* key : {"t_ns", "width", "height"}) {
    const std::size_t end = input.find('\n', at);
    if (end == std::string::npos) return 0;
    req.params.emplace(key, input.substr(at, end - at));
    at = end + 1;
  }
  req.body = input.substr(at);
  try {
    const orbatlas::RawFrame frame = orbatlas::parse_raw_frame(req, cv::Size(8, 4), (size & 1) != 0);
    if (frame.left.cols != 8 || frame.left.rows != 4) __builtin_trap();
  } catch (const orbatlas::Error&) {
  }
  return 0;
}
