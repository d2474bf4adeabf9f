#pragma once
// Conversions between the atlas's values and SQL columns, on either database
// (sql_connection.h): 64-bit ids (unsigned in memory, SQLite INTEGER /
// PostgreSQL bigint: signed) and poses (7 REAL / double precision columns
// qw qx qy qz tx ty tz).
#include <cstdint>
#include <string>

#include "core/geometry/pose.h"
#include "core/persistence/sql_connection.h"

namespace orbatlas {

// Ids are stored as signed 64-bit integers: throws Error for an id >= 2^63,
// which an allocator counting from 0 never reaches.
std::int64_t sql_id(std::uint64_t id);
// A stored id, which the schema keeps >= 0; DataError otherwise.
std::uint64_t id_column(const SqlStatement& row, int column);

// Binds parameters first_index .. first_index + 6.
void bind_pose(SqlStatement& statement, int first_index, const Pose3& pose);
// Columns first_column .. first_column + 6, exactly as stored: the quaternion is
// not renormalised (the schema CHECKs its norm), so a pose round-trips bit for bit.
Pose3 pose_columns(const SqlStatement& row, int first_column);

}  // namespace orbatlas
