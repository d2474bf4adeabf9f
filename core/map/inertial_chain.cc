#include "core/map/inertial_chain.h"

#include <algorithm>

namespace orbatlas {

std::vector<std::shared_ptr<KeyFrame>> inertial_chain(const std::shared_ptr<KeyFrame>& newest,
                                                      std::size_t max_keyframes) {
  std::vector<std::shared_ptr<KeyFrame>> chain;
  std::shared_ptr<KeyFrame> current = newest;
  while (current && !current->is_bad() && chain.size() < max_keyframes) {
    chain.push_back(current);
    const auto link = current->inertial_link();
    if (!link) break;
    auto previous = link->previous.lock();
    if (!previous || previous->map_id() != current->map_id()) break;
    current = std::move(previous);
  }
  std::reverse(chain.begin(), chain.end());
  return chain;
}

}  // namespace orbatlas
