#pragma once
// What the map server is started with (orbatlas serve's flags): its database,
// configs, the SLAM options its sessions start from, limits, merging,
// background priority and replica settings. AtlasService checks them first.
#include <cstddef>
#include <filesystem>

#include "core/persistence/atlas_checkpointer.h"
#include "core/server/map_merge_worker.h"
#include "core/server/replica_registry.h"
#include "core/slam/slam_system.h"

namespace orbatlas {

struct AtlasServiceOptions {
  std::filesystem::path db;          // created when missing
  std::filesystem::path config_dir;  // named configs: <config_dir>/<name>.yaml; empty: the shipped ones
  std::filesystem::path vocabulary;  // empty: the shipped one
  CheckpointOptions checkpoints;
  SlamSystemOptions slam;
  std::size_t max_live_sessions = 8;
  // A live session without a frame or IMU batch for this long is finished by
  // the server (stored like any other, status "ended_by": "idle_timeout"), so
  // abandoned sessions cannot hold the live-session slots. <= 0: never.
  double idle_timeout_s = 300.0;
  // A stereo mapping session that ends in a map other sessions mapped too
  // waits (in its finish) at most this long for a global BA of that map when
  // the map grew since its last one (SlamSystemOptions::shared_map_finish_wait_s),
  // so the trajectory read after the finish has it. 0: no such adjustment.
  double finish_refinement_wait_s = 15.0;
  // A finished session's maps are handed to the server-wide merging worker,
  // which merges them into a map of the atlas they share a place with.
  bool merge_maps = true;
  // With merge_maps: a live session's map is also merged WHILE it runs, when
  // place recognition finds a free map of the atlas made with the same camera
  // rig that shares a place with it (SlamSystemOptions::live_merging); the
  // session's tracking follows into that map.
  bool live_merging = true;
  // A new session first looks for its place in the free stored maps: found, it
  // tracks in that map's frame from its first frame (TrackerOptions::start_in_stored_map).
  bool start_in_stored_maps = true;
  // Loop closing (place recognition and correction in a session's own map) runs
  // on one server-wide thread for every session, with a queue this long
  // (a full queue skips a keyframe, counted in the session's loop statistics).
  std::size_t loop_queue = 64;
  MapMergeWorkerOptions merging;
  // The nice value (0..19) of every background thread: local mapping, loop
  // closing and its global BAs, map merging, checkpoints (thread_priority.h).
  // Above 0 the sessions' tracking is served first on a loaded machine and
  // mapping takes the cores' rest; a session that is not real-time (no
  // max_lag_s) then waits for its mapping at each keyframe, so that a stream
  // sent as fast as the server answers cannot starve it (docs/server.md,
  // "Serving live sessions first"). 0: every thread alike.
  int background_nice = 10;
  // A real-time session's frame (one with max_lag_s) waits at most this long
  // for the atlas's maps while an edit holds them (a merge, a loop correction,
  // a global BA's result or an inertial initialisation being applied); past it
  // the frame is answered untracked, `maps_busy` (SlamSystemOptions::max_maps_wait_ms).
  // 0: it waits for the edit, however long.
  double max_maps_wait_ms = 50.0;
  // This server as one replica of the atlas's database (replica_registry.h).
  ReplicaOptions replica;

  // Throws Error naming the first value out of range (also of the parts).
  void check() const;
};

}  // namespace orbatlas
