#pragma once
// Decodes the frames of a recording (stereo pairs, single images, colour and
// depth) ahead of their consumer, on a thread of its own, into a bounded queue
// (a few frames: memory stays flat). Used by
// `orbatlas run` (dataset_runner) and `orbatlas stream` (dataset_streamer). A
// frame with an empty right path is a single camera's: only `left` is read. An
// RGB-D recording's second image is its depth image, read as it is (16-bit).
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/common/bounded_queue.h"
#include "core/io/euroc_reader.h"

namespace orbatlas {

struct LoadedFrame {
  TimestampNs t_ns = 0;
  cv::Mat left, right;  // 8-bit grey; `right` the 16-bit depth for an RGB-D recording
  std::string error;    // non-empty when an image could not be read (the pair is then empty)
};

class FrameLoader {
 public:
  enum class Second { kImage, kDepth };
  explicit FrameLoader(std::vector<DatasetFrame> frames, std::size_t capacity = 4, Second second = Second::kImage);
  ~FrameLoader();  // stops the thread (pairs not taken are dropped)
  FrameLoader(const FrameLoader&) = delete;
  FrameLoader& operator=(const FrameLoader&) = delete;

  // The next pair in order; nullopt after the last one.
  std::optional<LoadedFrame> next() { return queue_.pop(); }

 private:
  const std::vector<DatasetFrame> frames_;
  BoundedQueue<LoadedFrame> queue_;
  std::thread thread_;  // last: started once the queue exists
};

}  // namespace orbatlas
