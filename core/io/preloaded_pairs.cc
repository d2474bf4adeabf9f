#include "core/io/preloaded_pairs.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/common/error.h"

namespace orbatlas {
namespace {

std::string errno_text() { return std::strerror(errno); }

}  // namespace

PreloadedPairs::PreloadedPairs() : fd_(::memfd_create("orbatlas-preloaded-pairs", MFD_CLOEXEC)) {
  ORBATLAS_CHECK(fd_ >= 0, "preload: cannot make an in-memory file for the decoded frames: " << errno_text());
}

PreloadedPairs::~PreloadedPairs() {
  if (fd_ >= 0) ::close(fd_);
}

PreloadedPairs::Image PreloadedPairs::write(const cv::Mat& image) {
  Image at;
  if (image.empty()) return at;
  const cv::Mat continuous = image.isContinuous() ? image : image.clone();
  at.rows = continuous.rows;
  at.cols = continuous.cols;
  at.type = continuous.type();
  at.offset = end_;
  at.bytes = continuous.total() * continuous.elemSize();
  const auto* data = reinterpret_cast<const char*>(continuous.data);
  std::uint64_t done = 0;
  while (done < at.bytes) {
    const ssize_t n = ::pwrite(fd_, data + done, at.bytes - done, static_cast<off_t>(at.offset + done));
    if (n < 0 && errno == EINTR) continue;
    ORBATLAS_CHECK(n > 0, "preload: cannot hold frame pixels past " << (at.offset + done) / (1u << 20)
                                                                    << " MB in memory: " << errno_text());
    done += static_cast<std::uint64_t>(n);
  }
  end_ += at.bytes;
  return at;
}

cv::Mat PreloadedPairs::read(const Image& image, cv::Mat& buffer) const {
  if (image.bytes == 0) return {};
  buffer.create(image.rows, image.cols, image.type);  // reallocates only when the shape changes
  auto* data = reinterpret_cast<char*>(buffer.data);
  std::uint64_t done = 0;
  while (done < image.bytes) {
    const ssize_t n = ::pread(fd_, data + done, image.bytes - done, static_cast<off_t>(image.offset + done));
    if (n < 0 && errno == EINTR) continue;
    ORBATLAS_CHECK(n > 0, "preload: cannot read back frame pixels at " << image.offset + done << ": "
                                                                       << (n == 0 ? "end of file" : errno_text()));
    done += static_cast<std::uint64_t>(n);
  }
  return buffer;
}

void PreloadedPairs::push(const LoadedFrame& pair) {
  Entry e;
  e.t_ns = pair.t_ns;
  e.error = pair.error;
  e.left = write(pair.left);
  e.right = write(pair.right);
  entries_.push_back(std::move(e));
}

std::optional<LoadedFrame> PreloadedPairs::pop() {
  if (next_ >= entries_.size()) return std::nullopt;
  const Entry& e = entries_[next_++];
  LoadedFrame pair;
  pair.t_ns = e.t_ns;
  pair.error = e.error;
  pair.left = read(e.left, left_buffer_);
  pair.right = read(e.right, right_buffer_);
  // The file's pages go back as the pairs are taken, as a queue's images
  // would. Best effort: where the file system cannot, they stay until the end.
  for (const Image* image : {&e.left, &e.right})
    if (image->bytes > 0)
      (void)::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, static_cast<off_t>(image->offset),
                        static_cast<off_t>(image->bytes));
  return pair;
}

}  // namespace orbatlas
