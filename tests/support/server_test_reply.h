#pragma once
// The reply checks of the HTTP tests: a status and the JSON error code.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas::test {

struct Reply {
  int status = 0;
  std::string code;
};

inline Reply classify(const httplib::Result& r) {
  if (!r) return {-1, "no reply: " + httplib::to_string(r.error())};
  if (r->status < 400) return {r->status, ""};
  try {
    return {r->status, nlohmann::json::parse(r->body).at("error").at("code").get<std::string>()};
  } catch (const std::exception&) {
    return {r->status, "(not a JSON error body: '" + r->body.substr(0, 80) + "')"};
  }
}

#define EXPECT_REPLY(result, status_, code_)                                \
  do {                                                                      \
    const ::orbatlas::test::Reply got = ::orbatlas::test::classify(result); \
    EXPECT_EQ(got.status, status_) << got.code;                             \
    EXPECT_EQ(got.code, code_) << "status " << got.status;                  \
  } while (0)

inline std::string png_of(const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  cv::imencode(".png", image, bytes);
  return std::string(bytes.begin(), bytes.end());
}

}  // namespace orbatlas::test
