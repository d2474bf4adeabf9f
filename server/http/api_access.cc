#include "server/http/api_access.h"

#include "core/server/service_error.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas {

std::optional<ApiClient> ApiAccess::client_of(const httplib::Request& req) const {
  if (credentials_.open()) return ApiClient{"", ClientRole::kOperator};
  return credentials_.authenticate(req.get_header_value("Authorization"));
}

void ApiAccess::set_owner(std::uint64_t id, const ApiClient& client) {
  if (credentials_.open()) return;
  std::lock_guard lock(mutex_);
  owners_[id] = client.name;
}

std::optional<std::string> ApiAccess::owner(std::uint64_t id) const {
  std::lock_guard lock(mutex_);
  const auto it = owners_.find(id);
  if (it == owners_.end()) return std::nullopt;
  return it->second;
}

void ApiAccess::require_owner(const httplib::Request& req, std::uint64_t id, bool finishing) const {
  if (credentials_.open()) return;
  const std::optional<ApiClient> client = client_of(req);
  const std::optional<std::string> started_by = owner(id);
  if (client && started_by && *started_by == client->name) return;
  if (client && finishing && client->role == ClientRole::kOperator) return;
  throw ServiceError(ServiceErrorKind::kForbidden, "forbidden",
                     "session " + std::to_string(id) + " belongs to " +
                         (started_by ? "client '" + *started_by + "'" : std::string("no client of this run")) +
                         (finishing ? " (an operator may finish it)" : ""));
}

void ApiAccess::count(const httplib::Request& req, int status) {
  const std::optional<ApiClient> client = client_of(req);
  const std::string name = credentials_.open() ? "-" : client ? client->name : "unauthenticated";
  const std::string role = client ? client_role_name(client->role) : "-";
  metrics_
      .counter("orbatlas_http_requests_total", "HTTP requests answered, by client, role and status class.",
               {{"client", name}, {"role", role}, {"status", std::to_string(status / 100) + "xx"}})
      .Increment();
}

}  // namespace orbatlas
