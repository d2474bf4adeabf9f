#pragma once
// Local mapping belongs to the map: one LocalMapper (a thread and a bounded
// queue) per map being mapped, fed by every session tracking in that map, and
// one LoopCloser over all of them (place recognition, loop correction, live
// merging, global BA). Sessions are trackers attached to this: each gets a
// KeyframeSink (attach()) that hands its keyframes to the mapping of the map
// they are in. When two sessions map the same map, both feed the same mapper.
//
// Who owns it: a SlamSystem on its own (offline runs, uploads) makes a private
// one; the server makes one per camera rig for all its mapping sessions, and
// `orbatlas run` with several recordings one for all of them (SessionWiring).
//
// Threads and locks (docs/architecture.md, "Shared maps"): mutex_ is a leaf,
// held only to look up or change the table of mappers, never while waiting on
// a mapper. Pausing a map (MappingControl) waits for its mapper outside it.
#include <chrono>
#include <cstdint>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <unordered_map>
#include <vector>

#include "core/camera/camera.h"
#include "core/common/worker_errors.h"
#include "core/loop/loop_closer.h"
#include "core/loop/mapping_control.h"
#include "core/map/atlas.h"
#include "core/mapping/local_mapper.h"
#include "core/tracking/frame_camera.h"
#include "core/tracking/keyframe_sink.h"

namespace orbatlas {

struct MappingWorkersOptions {
  LocalMapperOptions mapper;
  bool loop_closing = true;  // place recognition, loop correction, global BA
  LoopCloserOptions loop;    // live_merging: also merge maps live

  // Throws Error naming the first value out of range.
  void check() const;
};

class MappingWorkers final : public MappingControl {
 public:
  // `atlas` must outlive this; the camera is the rig's (every map mapped here
  // is of this rig; a copy of its model is kept, the caller's may go). The loop closer (when on) starts at once,
  // mappers when their map gets its first keyframe.
  MappingWorkers(Atlas& atlas, FrameCamera cam, MappingWorkersOptions options, LoopCloserWiring wiring = {});
  ~MappingWorkers() override;  // finish()
  MappingWorkers(const MappingWorkers&) = delete;
  MappingWorkers& operator=(const MappingWorkers&) = delete;

  // A session's sink for its tracker (must not outlive this). Its keyframes
  // form one stream for place recognition; the stream ends with the sink.
  std::unique_ptr<KeyframeSink> attach();

  // MappingControl (the loop closer).
  void pause(MapId map) override;
  void resume(MapId map) override;
  void merged(MapId source, MapId target) override;

  // Waits until the map's mapper has processed what it was handed (a session
  // that finishes: its keyframes are complete before it is stored).
  void wait_for_map(MapId map);
  // A session has ended in `map` (after wait_for_map): the loop closer's global
  // BA of the map when it is shared and has grown (LoopCloser::refine_at_stream_end),
  // waited for at most `max_wait`. True when applied or none was due (or no
  // loop closing).
  bool refine_at_stream_end(MapId map, std::chrono::milliseconds max_wait);
  // Waits until every mapper and the loop closer are idle (synchronous runs).
  void wait_until_idle();
  // The map's mapper stops once it has processed its queue (nobody maps the
  // map now: its thread goes). A later keyframe of the map starts a new one.
  void retire(MapId map);
  std::vector<MapId> mapped_maps() const;  // maps with a mapper now

  // Mappers finish (what is queued is processed), then the loop closer
  // (a running global adjustment is waited for). Idempotent; rethrows the
  // first fatal error. No keyframe may be handed in afterwards.
  void finish();

  // Figures of every mapper so far (also those retired), in processing order.
  LocalMapperStats mapping_stats() const;
  bool loop_closing() const { return loop_closer_ != nullptr; }
  LoopClosingStats loop_stats() const;  // empty without loop closing
  std::size_t errors() const;           // keyframes given up by mapping and loop closing

 private:
  class Sink;
  std::shared_ptr<LocalMapper> mapper_for(MapId map, bool create);  // null when none (and !create)
  bool insert(std::shared_ptr<KeyFrame> keyframe, std::uint64_t stream);
  void processed(const std::shared_ptr<KeyFrame>& keyframe);  // on a mapper thread
  // Stops a mapper that left the table (what it has queued is processed first)
  // and keeps its error counts; returns its fatal error, or logs it.
  std::exception_ptr finish_mapper(const std::shared_ptr<LocalMapper>& mapper);
  void finish_mapper_logged(const std::shared_ptr<LocalMapper>& mapper);
  WorkerErrorCounts mapping_errors() const;  // every mapper's, the retired ones' too
  void stream_ended(std::uint64_t stream);

  Atlas& atlas_;
  const std::unique_ptr<Camera> camera_;
  const FrameCamera cam_;  // camera: camera_
  const MappingWorkersOptions options_;
  const std::shared_ptr<LocalMapperStatsBoard> board_ = std::make_shared<LocalMapperStatsBoard>();

  mutable std::mutex mutex_;  // leaf: guards what follows
  std::map<MapId, std::shared_ptr<LocalMapper>> mappers_;
  std::set<MapId> paused_;
  std::unordered_map<KeyframeId, std::uint64_t> streams_;  // keyframes handed in, not yet processed
  std::uint64_t next_stream_ = 1;
  WorkerErrorCounts retired_errors_;
  bool finished_ = false;

  std::unique_ptr<LoopCloser> loop_closer_;  // null without loop closing
};

}  // namespace orbatlas
