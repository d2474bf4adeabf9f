#pragma once
// Conversions between the atlas's values and SQL columns: 64-bit ids (unsigned
// in memory, INTEGER in SQLite) and poses (7 REAL columns qw qx qy qz tx ty tz).
#include <cstdint>
#include <string>

#include "core/geometry/pose.h"
#include "core/persistence/sqlite_db.h"

namespace orbatlas {

// Ids are stored as SQLite INTEGER (signed 64-bit): throws Error for an id >= 2^63,
// which an allocator counting from 0 never reaches.
std::int64_t sql_id(std::uint64_t id);
// A stored id, which the schema keeps >= 0; DataError otherwise.
std::uint64_t id_column(const SqliteStatement& row, int column);

// Binds parameters first_index .. first_index + 6.
void bind_pose(SqliteStatement& statement, int first_index, const Pose3& pose);
// Columns first_column .. first_column + 6, exactly as stored: the quaternion is
// not renormalised (the schema CHECKs its norm), so a pose round-trips bit for bit.
Pose3 pose_columns(const SqliteStatement& row, int first_column);

}  // namespace orbatlas
