#pragma once
// Extracts a tar archive while it arrives: a producer (the HTTP handler reading an
// upload) hands chunks to write(), a thread of the extractor's own feeds them to
// extract_tar() through a bounded queue. Nothing is stored but the extracted
// files: no copy of the archive on disk, at most `queued_chunks` chunks in memory.
#include <atomic>
#include <cstddef>
#include <exception>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>

#include "core/archive/tar_reader.h"
#include "core/common/bounded_queue.h"

namespace orbatlas {

class TarStreamExtractor {
 public:
  TarStreamExtractor(std::filesystem::path destination, TarLimits limits, std::string archive_name,
                     std::size_t queued_chunks = 16);
  ~TarStreamExtractor();  // cancel()
  TarStreamExtractor(const TarStreamExtractor&) = delete;
  TarStreamExtractor& operator=(const TarStreamExtractor&) = delete;

  // Hands over the next bytes; blocks while the queue is full. False once the
  // extraction has failed (finish() then throws why) or was cancelled: stop
  // sending. Bytes after the archive's end (tar writers pad to whole records)
  // are accepted and dropped.
  bool write(const char* data, std::size_t size);
  enum class State { kReading, kSucceeded, kFailed };
  // kSucceeded once the end of the archive was reached, kFailed on an error.
  State state() const { return state_; }
  // The archive is complete: waits for the extraction and returns its report, or
  // throws its error (DataError for a bad archive).
  TarExtractReport finish();
  // The archive will not be completed (the upload was cut short or refused):
  // stops the extraction; what it wrote stays for the caller to delete.
  void cancel();

 private:
  void run();
  std::size_t read(char* buffer, std::size_t size);

  const std::filesystem::path destination_;
  const TarLimits limits_;
  const std::string archive_name_;
  BoundedQueue<std::string> chunks_;
  std::string current_;  // the chunk being read (extraction thread only)
  std::size_t current_offset_ = 0;
  std::atomic<bool> cancelled_{false};
  std::atomic<State> state_{State::kReading};
  std::optional<TarExtractReport> report_;  // set by the extraction thread before it ends
  std::exception_ptr error_;                // or this
  std::thread thread_;                      // last: started once everything above exists
};

}  // namespace orbatlas
