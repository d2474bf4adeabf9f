#pragma once
// An error the API reports to its client: an HTTP status, a short machine code
// and a message for humans. The service throws it; the HTTP layer turns it (and
// DataError, Error) into a JSON body (docs/api.md, "Errors").
#include <string>

#include "core/common/error.h"

namespace orbatlas {

class ApiError : public Error {
 public:
  ApiError(int status, std::string code, const std::string& message)
      : Error(message), status_(status), code_(std::move(code)) {}
  int status() const { return status_; }
  const std::string& code() const { return code_; }

 private:
  int status_;
  std::string code_;
};

[[noreturn]] inline void throw_not_found(const std::string& message) { throw ApiError(404, "not_found", message); }
[[noreturn]] inline void throw_bad_request(const std::string& message) { throw ApiError(400, "bad_request", message); }
[[noreturn]] inline void throw_conflict(const std::string& message) { throw ApiError(409, "conflict", message); }

}  // namespace orbatlas
