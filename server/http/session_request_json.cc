#include "server/http/session_request_json.h"

#include <nlohmann/json.hpp>

#include "core/server/service_error.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;

std::string optional_string(const json& body, const char* key) {
  if (!body.contains(key)) return {};
  if (!body[key].is_string()) throw_bad_request(std::string("'") + key + "' must be a string");
  return body[key].get<std::string>();
}

}  // namespace

SessionRequest parse_session_request(const std::string& body) {
  if (body.empty()) throw_bad_request("the request needs a JSON body");
  const json j = json::parse(body);  // json::exception: 400
  if (!j.is_object()) throw_bad_request("the JSON body must be an object");
  SessionRequest request;
  request.name = optional_string(j, "name");
  request.sensor = optional_string(j, "sensor");
  request.mode = optional_string(j, "mode");
  if (j.contains("max_lag_s")) {
    if (!j["max_lag_s"].is_number()) throw_bad_request("'max_lag_s' must be a number of seconds");
    request.max_lag_s = j["max_lag_s"].get<double>();
  }
  request.settings.config = optional_string(j, "config");
  request.settings.settings_yaml = optional_string(j, "settings_yaml");
  return request;
}

}  // namespace orbatlas
