#pragma once
// Who is calling, what they may do, and whose sessions are whose: the API's
// access checks (docs/api.md "Clients and roles"), shared by its routes.
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>

#include "core/server/metrics_registry.h"
#include "server/http/client_credentials.h"

namespace httplib {
struct Request;
}

namespace orbatlas {

class ApiAccess {
 public:
  explicit ApiAccess(ClientCredentials credentials) : credentials_(std::move(credentials)) {}

  bool open() const { return credentials_.open(); }
  // The caller (an open API: an anonymous operator); none when unknown.
  std::optional<ApiClient> client_of(const httplib::Request& req) const;

  // The session `id` was started by `client` (an open API records nobody).
  void set_owner(std::uint64_t id, const ApiClient& client);
  std::optional<std::string> owner(std::uint64_t id) const;
  // ServiceError 403 unless the caller started session `id`; an operator may
  // also finish (`finishing`) another's. Sessions nobody started here (stored
  // before a restart, uploads) are an operator's to finish only.
  void require_owner(const httplib::Request& req, std::uint64_t id, bool finishing) const;

  // One request answered: counted by client, role and status class.
  void count(const httplib::Request& req, int status);
  std::vector<prometheus::MetricFamily> metrics() const { return metrics_.collect(); }

 private:
  const ClientCredentials credentials_;
  mutable std::mutex mutex_;  // guards owners_
  std::map<std::uint64_t, std::string> owners_;
  mutable MetricsRegistry metrics_;  // thread-safe itself
};

}  // namespace orbatlas
