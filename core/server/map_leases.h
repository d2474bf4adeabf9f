#pragma once
// Which live session works in which map. Two sessions never track or map in one
// map at once (each has its own local mapping, which assumes it is the only
// writer besides its loop closer): a session may enter a stored map only while
// no other session holds it. The maps a session creates are its own until it
// finishes; then every map it held becomes free for the others.
//
// Thread-safe. claim() is what relocalisation asks (StereoSlamOptions::
// may_enter_map) while it tries candidates; a claim that does not end in
// tracking is given back by the settle() after that frame.
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <vector>

#include "core/common/ids.h"
#include "core/persistence/session_info.h"

namespace orbatlas {

class MapLeases {
 public:
  void add_free(MapId map);  // a stored map nobody works in
  // True when `session` may work in `map`: it holds it, or it was free (it is
  // then held tentatively).
  bool claim(SessionId session, MapId map);
  // True when no session holds or claims `map` (a stored map, or a finished session's).
  bool is_free(MapId map) const;
  // Like claim(), but held for good at once (a live merge into `map`: no
  // settle() may give it back before tracking has followed).
  bool hold(SessionId session, MapId map);
  // After a frame: the map the session tracked in (if any) is held for good;
  // its other tentative claims are given back.
  void settle(SessionId session, std::optional<MapId> tracked_in);
  // The session finished: every map it held is free.
  void release_all(SessionId session);
  // The map is gone (merged into another): nobody can hold or claim it.
  void forget(MapId map);
  std::optional<SessionId> holder(MapId map) const;
  std::vector<MapId> held_by(SessionId session) const;

 private:
  struct Lease {
    SessionId session = 0;
    bool tentative = false;
  };
  mutable std::mutex mutex_;
  std::set<MapId> free_;
  std::map<MapId, Lease> leases_;
};

}  // namespace orbatlas
