#pragma once
// SQL that takes an SQLite atlas's tables back from the latest schema to an
// older one, for the tests of a migration from that older schema (each test
// rolls its own step back and then every later step with these).

namespace orbatlas::test {

// Schema 18 (018_map_inertial_scale): the IMU's scale-factor correction of a
// map's inertial state. Runs inside the caller's transaction.
inline constexpr const char* kUndoSchema18Sqlite =
    "ALTER TABLE map_inertial_states DROP COLUMN sgx; ALTER TABLE map_inertial_states DROP COLUMN sgy; "
    "ALTER TABLE map_inertial_states DROP COLUMN sgz; ALTER TABLE map_inertial_states DROP COLUMN sax; "
    "ALTER TABLE map_inertial_states DROP COLUMN say; ALTER TABLE map_inertial_states DROP COLUMN saz; ";

}  // namespace orbatlas::test
