#pragma once
// The JSON body of POST /v1/sessions (docs/api.md): an object whose optional
// "name", "sensor", "mode", "config" and "settings_yaml" are strings and whose
// optional "max_lag_s" is a number. What the values mean is the service's to
// judge (AtlasService::create_session); this checks their shape only.
#include <string>

#include "core/server/session_request.h"

namespace orbatlas {

// ServiceError 400 (bad_request) for a body of another shape;
// nlohmann::json::exception for text that is not JSON (also a 400).
SessionRequest parse_session_request(const std::string& body);

}  // namespace orbatlas
