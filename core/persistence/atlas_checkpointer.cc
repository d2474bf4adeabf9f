#include "core/persistence/atlas_checkpointer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/thread_name.h"
#include "core/common/thread_priority.h"
#include "core/persistence/atlas_location.h"

namespace orbatlas {

using Clock = std::chrono::steady_clock;

void CheckpointOptions::check() const {
  ORBATLAS_CHECK(!std::isnan(every_seconds),
                 "atlas checkpoints: every_seconds (--checkpoint-seconds) must be a number (<= 0: no timer), not "
                     << every_seconds);
  ORBATLAS_CHECK(worker_nice >= 0 && worker_nice <= 19,
                 "atlas checkpoints: worker_nice must be in 0..19, not " << worker_nice);
}

AtlasCheckpointer::AtlasCheckpointer(const Atlas& atlas, const std::filesystem::path& path,
                                     const std::string& vocabulary_hash, CheckpointOptions options,
                                     std::optional<CheckpointSession> session)
    : path_(path),
      options_((options.check(), std::move(options))),
      writer_(atlas, AtlasStore::open(path, vocabulary_hash), std::move(session)) {
  // A checkpoint is superseded by the next one within seconds: a commit that
  // survives a crash of the process is enough (docs/schema.md).
  writer_.set_durable(false);
  if (options_.writable_maps) writer_.set_writable_maps(options_.writable_maps);
  if (options_.maps_changed) writer_.set_maps_changed(options_.maps_changed);
  worker_ = std::thread([this] { run(); });
}

AtlasCheckpointer::~AtlasCheckpointer() { stop(); }

void AtlasCheckpointer::notify_keyframe() {
  const std::size_t pending = pending_keyframes_.fetch_add(1) + 1;
  if (options_.every_keyframes == 0 || pending < options_.every_keyframes) return;
  // Under the mutex, so that the wake-up cannot fall between the worker's test
  // of the count and its wait.
  std::lock_guard lock(mutex_);
  wake_.notify_one();
}

void AtlasCheckpointer::notify_keyframe(SessionId session, KeyframeId keyframe) {
  {
    std::lock_guard lock(mutex_);
    attributions_.emplace_back(keyframe, session);
  }
  notify_keyframe();
}

void AtlasCheckpointer::add_session(CheckpointSession session) {
  std::lock_guard lock(mutex_);
  added_sessions_.push_back(std::move(session));
}

void AtlasCheckpointer::end_session(SessionId id) {
  std::lock_guard lock(mutex_);
  ended_sessions_.push_back(id);
}

void AtlasCheckpointer::drain_requests() {
  for (CheckpointSession& s : added_sessions_) {
    try {
      writer_.add_session(std::move(s));
    } catch (const std::exception& e) {
      log_warn(std::string("atlas checkpoints: ") + e.what());
    }
  }
  added_sessions_.clear();
  for (const SessionId id : ended_sessions_) writer_.end_session(id);
  ended_sessions_.clear();
  for (const auto& [keyframe, session] : attributions_) writer_.attribute_keyframe(keyframe, session);
  attributions_.clear();
}

bool AtlasCheckpointer::checkpoint_now() {
  std::unique_lock lock(mutex_);
  if (stopping_ || finished_) return false;
  const std::uint64_t ticket = ++requested_;
  wake_.notify_one();
  done_.wait(lock, [&] { return served_ >= ticket || finished_; });
  return served_ok_ >= ticket;
}

void AtlasCheckpointer::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  std::lock_guard join(join_mutex_);
  if (worker_.joinable()) worker_.join();
}

CheckpointStats AtlasCheckpointer::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

void AtlasCheckpointer::run() {
  set_current_thread_nice(options_.worker_nice);
  set_current_thread_name("checkpoints");
  const bool timed = options_.every_seconds > 0;
  // At most a year: a longer period would overflow the clock's deadline arithmetic.
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(std::min(options_.every_seconds, 3.15e7)));
  std::unique_lock lock(mutex_);
  while (true) {
    const auto due = [&] {
      return stopping_ || requested_ > served_ ||
             (options_.every_keyframes > 0 && pending_keyframes_.load() >= options_.every_keyframes);
    };
    if (timed) {
      wake_.wait_until(lock, Clock::now() + period, due);  // a timeout is a reason as well
    } else {
      wake_.wait(lock, due);
    }
    const bool final = stopping_;
    const std::uint64_t serving = requested_;  // every request so far was made before this checkpoint starts
    pending_keyframes_.store(0);
    drain_requests();
    lock.unlock();
    const bool ok = checkpoint_once(final);
    lock.lock();
    served_ = serving;
    if (ok) served_ok_ = serving;
    done_.notify_all();
    if (final) break;
  }
  finished_ = true;
  done_.notify_all();
}

bool AtlasCheckpointer::checkpoint_once(bool final) {
  const auto t0 = Clock::now();
  std::string error;
  CheckpointResult result;
  try {
    // The last checkpoint before the process may go away: wait for the disk.
    if (final) writer_.set_durable(true);
    result = writer_.checkpoint(options_.before_transaction);
  } catch (const std::exception& e) {
    error = e.what();
  } catch (...) {
    error = "unknown exception";
  }
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  std::unique_lock lock(mutex_);
  if (!error.empty()) {
    ++stats_.failures;
    stats_.last_error = error;
    stats_.last_failed = true;
    std::ostringstream line;
    line << "atlas checkpoint into " << location_for_messages(path_.string())
         << " failed (the file keeps the last committed state; the next checkpoint retries): " << error;
    lock.unlock();  // no I/O under the mutex notify_keyframe may take
    log_warn(line.str());
    return false;
  }
  ++stats_.checkpoints;
  stats_.last_failed = false;
  stats_.last_rows = result.rows;
  stats_.total_rows += result.rows;
  stats_.wall_ms.add(ms);
  stats_.last_ms = ms;
  if (result.committed) {
    ++stats_.commits;
    stats_.sequence = result.sequence;
  }
  return true;
}

}  // namespace orbatlas
