#include "core/slam/mapping_workers.h"

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/common/log.h"

namespace orbatlas {
namespace {

std::unique_ptr<Camera> copy_camera(const FrameCamera& cam) {
  ORBATLAS_CHECK(cam.camera != nullptr, "mapping needs a camera");
  return make_camera(cam.camera->calibration());
}

FrameCamera with_camera(FrameCamera cam, const Camera* camera) {
  cam.camera = camera;
  return cam;
}

void add_errors(WorkerErrorCounts& into, const WorkerErrorCounts& more) {
  into.errors += more.errors;
  if (!more.last.empty()) into.last = more.last;
  into.fatal = into.fatal || more.fatal;
}

}  // namespace

void MappingWorkersOptions::check() const {
  mapper.check();
  loop.check();
}

// One session's view: its keyframes go to the mapping of the map they are in.
class MappingWorkers::Sink final : public KeyframeSink {
 public:
  Sink(MappingWorkers& workers, std::uint64_t stream) : workers_(workers), stream_(stream) {}
  ~Sink() override { workers_.stream_ended(stream_); }
  Sink(const Sink&) = delete;
  Sink& operator=(const Sink&) = delete;

  bool idle(MapId map) const override {
    const auto mapper = workers_.mapper_for(map, false);
    return !mapper || mapper->idle(stream_);  // per session: see LocalMapper::idle
  }
  std::size_t queued(MapId map) const override {
    const auto mapper = workers_.mapper_for(map, false);
    return mapper ? mapper->queued() : 0;
  }
  bool accepting(MapId map) const override {
    {
      std::lock_guard lock(workers_.mutex_);
      if (workers_.paused_.contains(map)) return false;
    }
    const auto mapper = workers_.mapper_for(map, false);
    return !mapper || mapper->accepting();
  }
  void insert(std::shared_ptr<KeyFrame> keyframe) override {
    if (!workers_.insert(std::move(keyframe), stream_))
      throw Error("local mapping has finished; no keyframe can be inserted");
  }
  void interrupt_optimization(MapId map) override {
    if (const auto mapper = workers_.mapper_for(map, false)) mapper->interrupt_optimization(stream_);
  }
  bool wait_until_adjusted(MapId map, std::chrono::milliseconds at_most) override {
    if (!accepting(map)) return false;  // paused for a loop correction or a merge: do not wait for it
    const auto mapper = workers_.mapper_for(map, false);
    return !mapper || mapper->wait_until_adjusted(stream_, at_most);
  }

 private:
  MappingWorkers& workers_;
  const std::uint64_t stream_;
};

namespace {

// With a loop closer that runs global BAs, a map's full visual-inertial BA is
// one of them (in the background) rather than a stall of its local mapping.
MappingWorkersOptions with_deferred_inertial_ba(MappingWorkersOptions options) {
  options.mapper.defer_full_inertial_ba = options.loop_closing && options.loop.global_bundle_adjustment;
  return options;
}

}  // namespace

MappingWorkers::MappingWorkers(Atlas& atlas, FrameCamera cam, MappingWorkersOptions options, LoopCloserWiring wiring)
    : atlas_(atlas),
      camera_(copy_camera(cam)),
      cam_(with_camera(std::move(cam), camera_.get())),
      options_((options.check(), with_deferred_inertial_ba(std::move(options)))) {
  if (options_.loop_closing)
    loop_closer_ = std::make_unique<LoopCloser>(atlas_, cam_, *this, options_.loop, std::move(wiring));
}

MappingWorkers::~MappingWorkers() {
  try {
    finish();
  } catch (const std::exception& e) {
    log_warn(std::string("mapping stopped with an error: ") + e.what());
  }
}

std::unique_ptr<KeyframeSink> MappingWorkers::attach() {
  std::lock_guard lock(mutex_);
  ORBATLAS_CHECK(!finished_, "mapping has finished; no session can attach");
  return std::make_unique<Sink>(*this, next_stream_++);
}

std::shared_ptr<LocalMapper> MappingWorkers::mapper_for(MapId map, bool create) {
  std::shared_ptr<LocalMapper> mapper;
  bool pause = false;
  {
    std::lock_guard lock(mutex_);
    const auto it = mappers_.find(map);
    if (it != mappers_.end()) return it->second;
    if (!create || finished_) return nullptr;
    mapper = std::make_shared<LocalMapper>(atlas_, cam_, options_.mapper, &atlas_.keyframe_index(), board_);
    mapper->set_processed_listener([this](const std::shared_ptr<KeyFrame>& keyframe) { processed(keyframe); });
    mappers_.emplace(map, mapper);
    // A map paused before it had a mapper stays paused (the new mapper is idle:
    // this returns at once).
    pause = paused_.contains(map);
    if (pause) mapper->pause();
  }
  if (!pause) log_info("local mapping of map " + std::to_string(map) + " started");
  return mapper;
}

bool MappingWorkers::insert(std::shared_ptr<KeyFrame> keyframe, std::uint64_t stream) {
  {
    std::lock_guard lock(mutex_);
    streams_[keyframe->id()] = stream;
  }
  // A mapper retired between the look-up and the push refuses it: look again
  // (the keyframe's map may have changed too, by a merge).
  for (int attempt = 0; attempt < 3; ++attempt) {
    const auto mapper = mapper_for(keyframe->map_id(), true);
    if (!mapper) break;  // finished
    if (mapper->insert(keyframe, stream)) return true;
  }
  std::lock_guard lock(mutex_);
  streams_.erase(keyframe->id());
  return false;
}

void MappingWorkers::processed(const std::shared_ptr<KeyFrame>& keyframe) {
  std::uint64_t stream = 0;
  {
    std::lock_guard lock(mutex_);
    const auto it = streams_.find(keyframe->id());
    if (it != streams_.end()) {
      stream = it->second;
      streams_.erase(it);
    }
  }
  if (loop_closer_) loop_closer_->insert(keyframe, stream);
}

void MappingWorkers::stream_ended(std::uint64_t stream) {
  if (loop_closer_) loop_closer_->forget_stream(stream);
}

void MappingWorkers::pause(MapId map) {
  std::shared_ptr<LocalMapper> mapper;
  {
    std::lock_guard lock(mutex_);
    paused_.insert(map);
    const auto it = mappers_.find(map);
    if (it != mappers_.end()) mapper = it->second;
  }
  if (mapper) mapper->pause();  // outside mutex_: the mapper's listener takes it
}

void MappingWorkers::resume(MapId map) {
  std::shared_ptr<LocalMapper> mapper;
  {
    std::lock_guard lock(mutex_);
    paused_.erase(map);
    const auto it = mappers_.find(map);
    if (it != mappers_.end()) mapper = it->second;
  }
  if (mapper) mapper->resume();
}

void MappingWorkers::merged(MapId source, MapId target) {
  std::shared_ptr<LocalMapper> mapper;
  {
    std::lock_guard lock(mutex_);
    paused_.erase(source);
    const auto it = mappers_.find(source);
    if (it == mappers_.end()) return;
    mapper = it->second;
    mappers_.erase(it);
  }
  log_info("local mapping of map " + std::to_string(source) + " ends: the map joined map " + std::to_string(target));
  // A keyframe handed in just before the pause may still wait in its queue (it
  // is in `target` now): it is processed here, while `target`'s mapper is still
  // paused, so the two never edit the joined map at once.
  mapper->resume();
  finish_mapper_logged(mapper);
}

std::exception_ptr MappingWorkers::finish_mapper(const std::shared_ptr<LocalMapper>& mapper) {
  std::exception_ptr fatal;
  try {
    mapper->finish();
  } catch (...) {
    fatal = std::current_exception();
  }
  std::lock_guard lock(mutex_);
  add_errors(retired_errors_, mapper->errors());
  return fatal;
}

void MappingWorkers::finish_mapper_logged(const std::shared_ptr<LocalMapper>& mapper) {
  if (const auto fatal = finish_mapper(mapper)) {
    try {
      std::rethrow_exception(fatal);
    } catch (const std::exception& e) {
      log_warn(std::string("local mapping stopped with an error: ") + e.what());
    }
  }
}

void MappingWorkers::wait_for_map(MapId map) {
  if (const auto mapper = mapper_for(map, false)) mapper->wait_until_idle();
}

bool MappingWorkers::refine_at_stream_end(MapId map, std::chrono::milliseconds max_wait) {
  return !loop_closer_ || loop_closer_->refine_at_stream_end(map, max_wait);
}

void MappingWorkers::wait_until_idle() {
  std::vector<std::shared_ptr<LocalMapper>> mappers;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, mapper] : mappers_) mappers.push_back(mapper);
  }
  for (const auto& mapper : mappers) mapper->wait_until_idle();
  if (loop_closer_) loop_closer_->wait_until_idle();
}

void MappingWorkers::retire(MapId map) {
  std::shared_ptr<LocalMapper> mapper;
  {
    std::lock_guard lock(mutex_);
    const auto it = mappers_.find(map);
    if (it == mappers_.end() || paused_.contains(map)) return;  // a loop closing edit holds it: later
    mapper = it->second;
    mappers_.erase(it);
  }
  log_info("local mapping of map " + std::to_string(map) + " ends: no session maps it now");
  finish_mapper_logged(mapper);
}

std::vector<MapId> MappingWorkers::mapped_maps() const {
  std::lock_guard lock(mutex_);
  std::vector<MapId> out;
  for (const auto& [id, mapper] : mappers_) out.push_back(id);
  return out;
}

void MappingWorkers::finish() {
  std::map<MapId, std::shared_ptr<LocalMapper>> mappers;
  {
    std::lock_guard lock(mutex_);
    if (finished_) return;
    finished_ = true;
    mappers.swap(mappers_);
  }
  // Mapping first: no keyframe reaches the loop closer afterwards.
  std::exception_ptr fatal;
  for (const auto& [id, mapper] : mappers)
    if (auto error = finish_mapper(mapper); error && !fatal) fatal = std::move(error);
  if (loop_closer_) {
    try {
      loop_closer_->finish();
    } catch (...) {
      if (!fatal) fatal = std::current_exception();
    }
  }
  if (fatal) std::rethrow_exception(fatal);
}

WorkerErrorCounts MappingWorkers::mapping_errors() const {
  std::lock_guard lock(mutex_);
  WorkerErrorCounts out = retired_errors_;
  for (const auto& [id, mapper] : mappers_) add_errors(out, mapper->errors());
  return out;
}

LocalMapperStats MappingWorkers::mapping_stats() const {
  LocalMapperStats out;
  {
    std::lock_guard lock(board_->mutex);
    out = board_->stats;
  }
  out.errors = mapping_errors();
  return out;
}

LoopClosingStats MappingWorkers::loop_stats() const {
  if (loop_closer_) return loop_closer_->stats();
  return LoopClosingStats();
}

std::size_t MappingWorkers::errors() const {
  return mapping_errors().errors + (loop_closer_ ? loop_closer_->errors().errors : 0);  // cheap: no figures copied
}

}  // namespace orbatlas
