#include "server/http/http_router.h"

#include <new>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/parse_integer.h"

namespace orbatlas::http_detail {

void reply_json(Response& res, const json& body, int status) {
  res.status = status;
  // Text that is not UTF-8 (from an older database) is replaced, never a 500.
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

std::string redacted(std::string message, const Redactions& redactions) {
  for (const auto& [from, to] : redactions) {
    if (from.empty()) continue;
    for (std::size_t at = 0; (at = message.find(from, at)) != std::string::npos; at += to.size())
      message.replace(at, from.size(), to);
  }
  return message;
}

int http_status(ServiceErrorKind kind) {
  switch (kind) {
    case ServiceErrorKind::kBadRequest:
      return 400;
    case ServiceErrorKind::kNotFound:
      return 404;
    case ServiceErrorKind::kConflict:
      return 409;
    case ServiceErrorKind::kForbidden:
      return 403;
    case ServiceErrorKind::kTooLarge:
      return 413;
    case ServiceErrorKind::kUnprocessable:
      return 422;
    case ServiceErrorKind::kFailed:
      return 500;
    case ServiceErrorKind::kUnavailable:
      return 503;
  }
  return 500;
}

void reply_error(Response& res, int status, const std::string& code, const std::string& message) {
  reply_json(res, {{"error", {{"code", code}, {"message", message}}}}, status);
}

void run_guarded(const ErrorContext& context, const Request& req, Response& res, const std::function<void()>& handler) {
  const auto error = [&](int status, const std::string& code, const std::string& message) {
    reply_error(res, status, code, redacted(message, context.redactions));
  };
  try {
    handler();
  } catch (const ServiceError& e) {
    error(http_status(e.kind()), e.code(), e.what());
  } catch (const DataError& e) {
    error(422, "bad_input", e.what());
  } catch (const json::exception& e) {
    error(400, "bad_json", std::string("malformed request: ") + e.what());
  } catch (const std::bad_alloc&) {
    log_warn(req.method + " " + req.path + ": out of memory");
    error(503, "unavailable", "the server ran out of memory for this request");
  } catch (const std::exception& e) {
    log_warn(req.method + " " + req.path + ": " + e.what());
    error(500, "internal", e.what());
  }
}

std::uint64_t id_from(const Request& req, std::size_t group, const char* what) {
  const std::string& text = req.matches[group];
  const auto id = parse_integer<std::uint64_t>(text);
  if (!id) throw_not_found(std::string("no ") + what + " " + text);
  return *id;
}

}  // namespace orbatlas::http_detail
