#pragma once
// Which live sessions work in which map. Mapping sessions share the maps they
// are in (their keyframes go to the map's one local mapper, MappingWorkers), so
// a map may have several holders; what leases still guard is ownership for the
// offline merging worker, which takes a map exclusively (no session may enter
// it while it merges, and it merges no map a session works in). Localisations
// hold nothing: they change nothing.
//
// Thread-safe. claim() is what relocalisation asks (SessionWiring::
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
  // True when `session` may work in `map`: it holds it, or the map is known
  // (stored, or settled by a live session) and nobody holds it exclusively;
  // it is then held tentatively until settle().
  bool claim(SessionId session, MapId map);
  // Exclusive (the merging worker): true when `owner` holds `map` alone
  // afterwards; false while anyone else holds or claims it.
  bool claim_exclusive(SessionId owner, MapId map);
  // True when nobody holds or claims `map` (a stored map, or a finished session's).
  bool is_free(MapId map) const;
  // A live merge of `source` into `target`: every holder of `source` holds
  // `target` for good from now on. False when `target` is held exclusively.
  bool share(MapId source, MapId target);
  // After a frame: the map the session tracked in (if any) is held for good;
  // its other tentative claims are given back.
  void settle(SessionId session, std::optional<MapId> tracked_in);
  // The session finished: it holds nothing now.
  void release_all(SessionId session);
  // The map is gone (merged into another): nobody can hold or claim it.
  void forget(MapId map);
  std::vector<SessionId> holders(MapId map) const;  // by id, tentative ones too
  std::vector<MapId> held_by(SessionId session) const;

 private:
  struct Lease {
    bool tentative = false;
    bool exclusive = false;
  };
  void give_back(MapId map, SessionId session);  // mutex_ held

  mutable std::mutex mutex_;  // leaf
  std::set<MapId> free_;
  std::map<MapId, std::map<SessionId, Lease>> leases_;  // never an empty inner map
};

}  // namespace orbatlas
