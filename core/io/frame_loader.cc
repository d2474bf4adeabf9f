#include "core/io/frame_loader.h"

#include <opencv2/imgcodecs.hpp>

namespace orbatlas {

FrameLoader::FrameLoader(std::vector<DatasetFrame> frames, std::size_t capacity, Second second)
    : frames_(std::move(frames)), queue_(capacity) {
  const int second_flags = second == Second::kDepth ? cv::IMREAD_UNCHANGED : cv::IMREAD_GRAYSCALE;
  thread_ = std::thread([this, second_flags] {
    for (const DatasetFrame& f : frames_) {
      LoadedFrame pair;
      pair.t_ns = f.t_ns;
      pair.left = cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE);
      const bool single = f.right.empty();  // a single camera's frame
      if (!single) pair.right = cv::imread(f.right.string(), second_flags);
      if (pair.left.empty())
        pair.error = "cannot read image " + f.left.string();
      else if (!single && pair.right.empty())
        pair.error = "cannot read image " + f.right.string();
      if (!queue_.push(std::move(pair))) return;  // closed: the consumer stopped
    }
    queue_.close();
  });
}

FrameLoader::~FrameLoader() {
  queue_.close();
  thread_.join();
}

}  // namespace orbatlas
