#pragma once
// Which maps of a shared (PostgreSQL) atlas this replica writes
// (schema/011_map_owners, docs/scaling.md "Replicas"). Every replica reads every
// map; a map is written (mapped in, merged, checkpointed) by the replica that
// owns it in `map_owners`:
// - a map this replica makes (its id in the replica's range) is claimed by the
//   checkpoint that first writes it;
// - stored maps that nobody owns (written by `orbatlas run`, or by a server
//   before replicas) and the maps of dead replicas (lease passed) are taken
//   over by claim_free_and_dead(), after which the caller reads them again
//   from the database and then calls ready(): only then are they written, so
//   a stale copy never overwrites what the dead owner committed last.
// - a live replica may ask for another's map (want(): it has merge work for
//   it); the owner hands it over (hand_over()) once nobody works in it there,
//   after a checkpoint, and the new owner takes it like a dead replica's map
//   (claim_free_and_dead() returns it, read again, then ready()).
// A checkpoint asks writable() inside its transaction, which locks this
// replica's ownership rows (FOR SHARE): a takeover by another replica waits for
// that checkpoint, and this replica writes nothing of the map afterwards. A
// replica whose own lease passed writes nothing at all.
//
// Thread-safe (the checkpoint thread, the takeover thread, request threads).
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <unordered_set>
#include <vector>

#include "core/common/ids.h"
#include "core/persistence/sql_connection.h"
#include "core/server/replica_registry.h"

namespace orbatlas {

class PgDb;

class MapOwnership {
 public:
  // `registry` (shared, on PostgreSQL) must outlive this.
  explicit MapOwnership(const ReplicaRegistry& registry, std::string location);
  ~MapOwnership();
  MapOwnership(const MapOwnership&) = delete;
  MapOwnership& operator=(const MapOwnership&) = delete;

  // Claims the stored maps without an owner and those owned by dead replicas
  // (one transaction, on a connection of its own); returns the maps claimed
  // now, and those another replica handed over since. They are written only
  // once ready(). Error when the database cannot be reached.
  std::vector<MapId> claim_free_and_dead();
  // The claimed maps have been read again from the database: they may be written.
  void ready(const std::vector<MapId>& maps);
  // True when this replica may write `map` (it made it, or took it over and
  // read it again, and has not handed it over since).
  bool owns(MapId map) const;

  // Asks the replica that owns `map` to hand it over (merge work for it
  // waits here). False when this replica owns it, or nobody does.
  bool want(MapId map);
  struct Wanted {
    MapId map = 0;
    std::uint64_t by = 0;  // a live replica
  };
  // This replica's maps that a live replica asked for.
  std::vector<Wanted> wanted() const;
  // Gives `map` to replica `to` (after the caller checkpointed it and while
  // nothing works in it here); from then on it is not owns(). False when it
  // was not this replica's in the database.
  bool hand_over(MapId map, std::uint64_t to);

  // CheckpointOptions::writable_maps: of `candidates`, the maps this replica
  // owns in the database (claiming those it made and has neither handed over
  // nor merged away), locked for the transaction open on `db`; the ownership
  // of the maps this checkpoint deletes (`gone`: merged away in its snapshot)
  // is deleted with their rows. A map merged away after the snapshot keeps its
  // owner row: the checkpoint still writes it as it was.
  std::unordered_set<MapId> writable(SqlConnection& db, const std::vector<MapId>& candidates,
                                     const std::unordered_set<MapId>& gone);

  // CheckpointOptions::maps_changed: the versions of the maps this replica
  // owns and the checkpoint changed go up, in its transaction.
  void changed(SqlConnection& db, const std::vector<MapId>& maps);

  struct Owned {
    MapId map = 0;
    std::uint64_t replica = 0;
    std::int64_t version = 0;  // grows with every checkpoint that changed it
  };
  // Every owned map of the database now (Error when it cannot be reached).
  std::vector<Owned> owners() const;

 private:
  bool made_here(MapId map) const { return replica_id_range(registry_.id(), kReplicaMapIdShift).contains(map); }
  bool handed_over(MapId map) const;

  const ReplicaRegistry& registry_;
  const std::string location_;
  mutable std::mutex db_mutex_;  // guards db_ (claims, owners())
  mutable std::unique_ptr<PgDb> db_;
  mutable std::mutex mutex_;  // leaf; guards ready_, given_
  std::set<MapId> ready_;     // taken over and read again (maps made here need not be)
  std::set<MapId> given_;     // handed over to another replica (made here or not)
};

}  // namespace orbatlas
