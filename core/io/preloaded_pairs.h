#pragma once
// Decoded stereo pairs held in an anonymous in-memory file (memfd), read back
// one pair at a time into two buffers reused from pair to pair.
//
// Why not a queue of cv::Mat: a minute of a 20 Hz stereo clip is 860 MB of
// pixels, and on the VM the capacity benchmark runs on, the kernel's memory
// monitor (DAMON, kdamond) samples mapped pages every 0.5 s and its cost grows
// with the memory processes map: four clients holding their clips as images
// made it take ~10 ms of a core at a time, and most late frames fell in those
// moments (docs/benchmarks.md). Pages of a memfd the process never
// maps cost the monitor nothing, and the pair is copied in (pread) just before
// it is sent.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "core/io/frame_loader.h"

namespace orbatlas {

class PreloadedPairs {
 public:
  PreloadedPairs();  // throws Error if the in-memory file cannot be made
  ~PreloadedPairs();
  PreloadedPairs(const PreloadedPairs&) = delete;
  PreloadedPairs& operator=(const PreloadedPairs&) = delete;

  // Appends a pair (its images in any layout; stored continuous). Throws Error
  // when the file cannot take it (out of memory).
  void push(const LoadedFrame& pair);

  // The next pair in the order pushed; nullopt after the last. Its images
  // share this object's two buffers: valid until the next pop().
  std::optional<LoadedFrame> pop();

  std::size_t size() const { return entries_.size() - next_; }  // pairs not popped yet
  std::uint64_t bytes() const { return end_; }                  // pixels held, in bytes

 private:
  struct Image {
    int rows = 0, cols = 0, type = 0;
    std::uint64_t offset = 0, bytes = 0;
  };
  struct Entry {
    TimestampNs t_ns = 0;
    std::string error;
    Image left, right;
  };
  Image write(const cv::Mat& image);
  cv::Mat read(const Image& image, cv::Mat& buffer) const;

  int fd_ = -1;
  std::uint64_t end_ = 0;
  std::vector<Entry> entries_;
  std::size_t next_ = 0;
  cv::Mat left_buffer_, right_buffer_;
};

}  // namespace orbatlas
