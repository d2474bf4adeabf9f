#pragma once
// The server's sessions: the live ones and those stored by earlier runs (or
// by other replicas), each with what it was started with (SessionStart), the
// next session id, the limit on live sessions, the shutdown flag, and the
// idle-expiry thread that finishes live sessions without a frame or IMU batch
// for the idle timeout. Thread-safe; its mutex is taken under no other lock
// of the service and takes only reads of the sessions' atomics under it.
#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "core/common/ids.h"
#include "core/optimization/global_bundle_adjustment.h"
#include "core/persistence/map_rigs.h"
#include "core/server/live_session.h"
#include "core/server/session_request.h"

namespace orbatlas {

// What a session of this run was started with.
struct SessionStart {
  SettingsSource settings;
  KeyframeId first_keyframe = 0;  // keyframe ids from here on are this session's or later ones
  // A mapping session that fuses its IMU: the merging worker's global BAs keep the IMU terms.
  std::optional<GlobalBundleAdjustmentOptions::Inertial> inertial;
  MapRig rig;  // what it maps with
};

class SessionRegistry {
 public:
  explicit SessionRegistry(std::size_t max_live_sessions);
  ~SessionRegistry();  // stop()
  SessionRegistry(const SessionRegistry&) = delete;
  SessionRegistry& operator=(const SessionRegistry&) = delete;

  // An id for a new live session: ServiceError 503 when the server is shutting
  // down ("shutting_down") or max_live_sessions are live ("too_many_sessions").
  SessionId reserve_id();
  // Ids handed out from `first` on (a replica's own range), and never below a
  // stored session's.
  void start_ids_at(SessionId first);
  void add_live(SessionId id, std::shared_ptr<LiveSession> session, SessionStart start);
  // A stored session (loaded at start, or another replica's found later): added
  // unless the id is known; returns whether it was. `own_id`: the next id
  // handed out comes after it.
  bool add_stored(std::shared_ptr<LiveSession> session, bool own_id);
  bool contains(SessionId id) const;

  std::shared_ptr<LiveSession> get(SessionId id) const;   // ServiceError 404
  std::vector<std::shared_ptr<LiveSession>> all() const;  // by id
  std::vector<std::shared_ptr<LiveSession>> active() const;
  std::optional<SessionStart> start_of(SessionId id) const;  // none for a session this run did not start
  // The rig a session maps with (a stored session's from its sensor and cameras).
  MapRig mapping_rig(SessionId id) const;
  // Live sessions whose last frame was tracked in `map`.
  std::vector<SessionId> in_map(MapId map) const;
  struct Counts {
    std::size_t live = 0, ended = 0, worker_errors = 0;
  };
  Counts counts() const;
  std::size_t size() const;

  // Finishes (through `finish`) every live session idle for `timeout_s` (> 0),
  // on a thread of its own until stop().
  void expire_idle_sessions(double timeout_s, std::function<void(SessionId)> finish);
  // No new sessions from now on; the idle-expiry thread ends (a finish it is
  // running completes first). Returns false when it was stopped already.
  bool stop();
  bool stopped() const;

 private:
  void expire_until_stopped(std::chrono::steady_clock::duration timeout, const std::function<void(SessionId)>& finish);

  const std::size_t max_live_sessions_;
  mutable std::mutex mutex_;  // guards everything below
  std::map<SessionId, std::shared_ptr<LiveSession>> sessions_;
  std::map<SessionId, SessionStart> starts_;  // of this run's sessions
  SessionId next_id_ = 1;
  bool stopped_ = false;
  std::condition_variable wake_;  // with mutex_: a session was added, or stop()
  std::thread idle_thread_;       // joined by stop()
};

}  // namespace orbatlas
