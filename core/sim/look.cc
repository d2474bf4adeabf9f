#include "core/sim/look.h"

#include "core/common/error.h"

namespace orbatlas::sim {

const char* look_name(Look look) { return look == Look::kReal ? "real" : "clean"; }

Look parse_look(const std::string& name) {
  if (name == "clean") return Look::kClean;
  if (name == "real") return Look::kReal;
  throw Error("unknown simulator look '" + name + "' (clean or real)");
}

RealLookOptions real_look_for(const std::string& sequence) {
  RealLookOptions o;
  if (sequence == "MH_04" || sequence == "MH_05") o.camera.illumination = 0.12;
  return o;
}

}  // namespace orbatlas::sim
