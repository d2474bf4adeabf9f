#pragma once
// The engine's tuning a user can set in a settings file: optional keys
// `Orbatlas.<Part>.<Name>` beside ORB-SLAM3's (docs/settings.md lists them with
// their defaults and ranges). Applied by SlamSystem to its options, after what it
// derives from the camera (so a key wins over a derived value).
#include <map>
#include <string>
#include <vector>

#include "core/slam/slam_system.h"

namespace orbatlas {

struct SlamTuningKey {
  std::string key;          // without "Orbatlas.", e.g. "Tracker.MinInliers"
  double min = 0, max = 0;  // the accepted range (inclusive)
  bool integer = false;     // whole numbers only (0 / 1 for switches)
  std::string meaning;
};

// Every key, in the order docs/settings.md lists them.
const std::vector<SlamTuningKey>& slam_tuning_keys();

// Sets `options` from `tuning` (SlamSettings::orbatlas). Throws DataError naming
// the key for an unknown key (with the known ones), a value out of range, a
// fraction where a whole number is needed, or a value the resulting options'
// check() refuses (e.g. Tracker.Relocalization 0 in a localisation run); `options`
// is unchanged then. Options already out of range give check()'s Error as is.
void apply_slam_tuning(const std::map<std::string, double>& tuning, SlamSystemOptions& options);

// The value of every key in `options` (for logs: what is in effect).
std::map<std::string, double> slam_tuning_values(const SlamSystemOptions& options);

}  // namespace orbatlas
