#pragma once
// The JSON of the service's answers (docs/api.md) and the PLY of a map's
// points: the only place that turns core/server's typed results into a wire format.
#include <nlohmann/json.hpp>
#include <string>

#include "core/persistence/atlas_store.h"
#include "core/server/replica_registry.h"
#include "core/server/service_results.h"

namespace orbatlas {

nlohmann::json to_json(const SessionStatus& status);
nlohmann::json to_json(const MapSummary& map);
nlohmann::json to_json(const MergesReport& merges);
nlohmann::json to_json(const HealthReport& health);
nlohmann::json to_json(const StoredJob& job);
// GET /v1/replicas: `self` is the answering replica's id.
nlohmann::json replicas_json(const std::vector<ReplicaInfo>& replicas, const ReplicaRegistry& self);

// ASCII PLY: one vertex per point (x y z, metres, 5 decimals), the map named in a comment.
std::string to_ply(const MapPointCloud& cloud);

}  // namespace orbatlas
