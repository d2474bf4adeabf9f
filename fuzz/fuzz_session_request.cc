// libFuzzer: the body of POST /v1/sessions (server/http/session_request_json.h)
// and, as the service then reads it, its inline settings_yaml
// (core/io/settings.h). Every input is a request, a 400 (ServiceError, JSON
// errors) or a settings Error; nothing else escapes, nothing crashes.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "core/common/error.h"
#include "core/io/settings.h"
#include "server/http/session_request_json.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const orbatlas::SessionRequest request =
        orbatlas::parse_session_request(std::string(reinterpret_cast<const char*>(data), size));
    if (!request.settings.settings_yaml.empty()) orbatlas::read_settings_text(request.settings.settings_yaml, "fuzz");
  } catch (const orbatlas::Error&) {
  } catch (const nlohmann::json::exception&) {
  }
  return 0;
}
