#pragma once
// The deterministic evolving atlas of the crash-safety test: state k is the
// result of steps 1..k applied to an empty atlas, and each step depends on k
// only (its own seeded generator), so the writer process and the test build
// exactly the same objects with the same ids. Each step is large enough that a
// checkpoint takes a while (thousands of rows and a few hundred KB of blobs),
// so that kills often land inside its transaction.
#include "core/map/atlas.h"

namespace orbatlas::test {

// Step k >= 1: new keyframes and points with observations, covisibility and
// parents; every keyframe of the active map moved (a correction); statistics;
// culled keyframes and points; loop edges; a new map now and then.
void apply_crash_step(Atlas& atlas, int k);

// The state after steps 1..k (k = 0: an empty atlas).
void build_crash_state(Atlas& atlas, int k);

}  // namespace orbatlas::test
