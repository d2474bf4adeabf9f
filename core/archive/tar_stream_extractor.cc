#include "core/archive/tar_stream_extractor.h"

#include <algorithm>
#include <cstring>

#include "core/common/error.h"

namespace orbatlas {

TarStreamExtractor::TarStreamExtractor(std::filesystem::path destination, TarLimits limits, std::string archive_name,
                                       std::size_t queued_chunks)
    : destination_(std::move(destination)),
      limits_(limits),
      archive_name_(std::move(archive_name)),
      chunks_(queued_chunks),
      thread_([this] { run(); }) {}

TarStreamExtractor::~TarStreamExtractor() { cancel(); }

bool TarStreamExtractor::write(const char* data, std::size_t size) {
  if (size > 0 && chunks_.push(std::string(data, size))) return true;
  return state_ == State::kSucceeded;
}

TarExtractReport TarStreamExtractor::finish() {
  chunks_.close();  // the extraction reads what is queued, then sees the end
  if (thread_.joinable()) thread_.join();
  if (error_) std::rethrow_exception(error_);
  ORBATLAS_CHECK(report_.has_value(), "tar extraction of " << archive_name_ << " ended without a result");
  return *report_;
}

void TarStreamExtractor::cancel() {
  cancelled_ = true;
  chunks_.close();
  if (thread_.joinable()) thread_.join();
}

std::size_t TarStreamExtractor::read(char* buffer, std::size_t size) {
  while (current_offset_ == current_.size()) {
    if (cancelled_) throw Error("tar: the upload of " + archive_name_ + " was cancelled");
    std::optional<std::string> next = chunks_.pop();
    if (!next) {
      if (cancelled_) throw Error("tar: the upload of " + archive_name_ + " was cancelled");
      return 0;  // closed and drained: the end of the archive
    }
    current_ = std::move(*next);
    current_offset_ = 0;
  }
  const std::size_t n = std::min(size, current_.size() - current_offset_);
  std::memcpy(buffer, current_.data() + current_offset_, n);
  current_offset_ += n;
  return n;
}

void TarStreamExtractor::run() {
  try {
    report_ = extract_tar([this](char* buffer, std::size_t size) { return read(buffer, size); }, destination_, limits_,
                          archive_name_);
    state_ = State::kSucceeded;
  } catch (...) {
    error_ = std::current_exception();
    state_ = State::kFailed;
  }
  // Failed, or done before the producer was: its next write() returns false
  // instead of waiting on a queue nobody reads.
  chunks_.close();
}

}  // namespace orbatlas
