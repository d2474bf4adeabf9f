#include "core/persistence/database_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_location.h"
#include "core/persistence/pg_writer_lock.h"

namespace orbatlas {
namespace {

std::string read_all(int fd) {
  std::string text;
  char chunk[256];
  ::lseek(fd, 0, SEEK_SET);
  for (ssize_t n; (n = ::read(fd, chunk, sizeof chunk)) > 0;) text.append(chunk, static_cast<std::size_t>(n));
  return text;
}

}  // namespace

DatabaseLock::DatabaseLock(const std::filesystem::path& db, DatabaseLockMode mode) {
  if (is_postgres_location(db.string())) {
    check_postgres_uri(db.string());
    pg_ = std::make_unique<PgWriterLock>(db.string(), mode == DatabaseLockMode::kShared);
    previous_crashed_ = pg_->previous_holder_crashed();
    return;
  }
  path_ = db.string() + ".lock";
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd_ < 0) throw Error("cannot open the lock file " + path_.string() + ": " + std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    const std::string holder = read_all(fd_);
    ::close(fd_);
    fd_ = -1;
    if (error == EWOULDBLOCK)
      throw Error("the atlas " + db.string() + " is in use by another process (" +
                  (holder.empty() ? std::string("lock file ") + path_.string() : holder.substr(0, holder.find('\n'))) +
                  "); one writer per database");
    throw Error("cannot lock " + path_.string() + ": " + std::strerror(error));
  }
  previous_crashed_ = read_all(fd_).rfind("running", 0) == 0;
  write_state("running pid " + std::to_string(::getpid()) + "\n");
}

DatabaseLock::~DatabaseLock() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the flock
}

void DatabaseLock::mark_stopped() {
  if (pg_) {
    pg_->mark_stopped();
    return;
  }
  write_state("stopped\n");
}

void DatabaseLock::write_state(const std::string& text) {
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size()) ||
      ::fsync(fd_) != 0)
    throw Error("cannot write the lock file " + path_.string() + ": " + std::strerror(errno));
}

void skip_ids_after_crash(Atlas& atlas) {
  IdAllocator& ids = atlas.ids();
  ids.ensure_above(IdKind::keyframe, ids.peek(IdKind::keyframe) + kKeyframeIdGapAfterCrash - 1);
  ids.ensure_above(IdKind::map_point, ids.peek(IdKind::map_point) + kMapPointIdGapAfterCrash - 1);
  ids.ensure_above(IdKind::map, ids.peek(IdKind::map) + kMapIdGapAfterCrash - 1);
}

}  // namespace orbatlas
