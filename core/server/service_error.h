#pragma once
// An error the service reports to its caller: a kind (what went wrong, in terms of
// the request), a short machine code and a message for humans. The service knows
// no transport: the HTTP layer (server/http/http_api.cc) maps each kind to a
// status code and turns the error (and DataError, Error) into a JSON body
// (docs/api.md, "Errors").
#include <string>

#include "core/common/error.h"

namespace orbatlas {

enum class ServiceErrorKind {
  kBadRequest,     // malformed, missing or out-of-range request fields, unusable settings
  kNotFound,       // no such session, map, job or configuration
  kConflict,       // the object's state does not allow it (frames for a finished session)
  kForbidden,      // the caller may not do this (another client's session)
  kUnprocessable,  // well-formed but not something this service does (a sensor it cannot map)
  kTooLarge,       // more data than the service takes
  kFailed,         // the work failed on the service's side (a session's tracking, storage)
  kUnavailable,    // not now: limits reached, shutting down, storage unavailable; retry later
};

class ServiceError : public Error {
 public:
  ServiceError(ServiceErrorKind kind, std::string code, const std::string& message)
      : Error(message), kind_(kind), code_(std::move(code)) {}
  ServiceErrorKind kind() const { return kind_; }
  const std::string& code() const { return code_; }

 private:
  ServiceErrorKind kind_;
  std::string code_;
};

[[noreturn]] inline void throw_not_found(const std::string& message) {
  throw ServiceError(ServiceErrorKind::kNotFound, "not_found", message);
}
[[noreturn]] inline void throw_bad_request(const std::string& message) {
  throw ServiceError(ServiceErrorKind::kBadRequest, "bad_request", message);
}
[[noreturn]] inline void throw_conflict(const std::string& message) {
  throw ServiceError(ServiceErrorKind::kConflict, "conflict", message);
}

}  // namespace orbatlas
