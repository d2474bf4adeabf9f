#pragma once
// Errors are exceptions carrying a readable message; library code never exits.
#include <sstream>
#include <stdexcept>
#include <string>

namespace orbatlas {

// Any failure a user can cause (bad file, bad argument, bad data).
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Input data that cannot be read or parsed; the message names the file and line.
class DataError : public Error {
 public:
  using Error::Error;
};

[[noreturn]] void throw_error(const std::string& message);

}  // namespace orbatlas

// ORBATLAS_CHECK(cond, "text" << value): throws orbatlas::Error when cond is false.
#define ORBATLAS_CHECK(cond, msg)                            \
  do {                                                       \
    if (!(cond)) {                                           \
      std::ostringstream orbatlas_check_stream_;             \
      orbatlas_check_stream_ << msg;                         \
      ::orbatlas::throw_error(orbatlas_check_stream_.str()); \
    }                                                        \
  } while (false)

// ORBATLAS_DATA_CHECK(cond, "text" << value): throws orbatlas::DataError (bad input data).
#define ORBATLAS_DATA_CHECK(cond, msg)                           \
  do {                                                           \
    if (!(cond)) {                                               \
      std::ostringstream orbatlas_check_stream_;                 \
      orbatlas_check_stream_ << msg;                             \
      throw ::orbatlas::DataError(orbatlas_check_stream_.str()); \
    }                                                            \
  } while (false)
