#include "core/common/error.h"

namespace orbatlas {

void throw_error(const std::string& message) { throw Error(message); }

}  // namespace orbatlas
