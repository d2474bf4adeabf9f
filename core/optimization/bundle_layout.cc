#include "core/optimization/bundle_layout.h"

#include <unordered_map>
#include <utility>

#include "core/common/error.h"

namespace orbatlas {

BundleLayout bundle_layout_of(const BundleProblem& lp) {
  BundleLayout l;
  l.pose_var.assign(lp.keyframes.size(), kNoBundleVar);
  std::vector<int> point_var(lp.points.size(), kNoBundleVar);
  std::vector<std::size_t> count;
  const auto free_pose = [&](std::size_t k) {
    if (lp.fixed[k]) return kNoBundleVar;
    if (l.pose_var[k] == kNoBundleVar) {
      l.pose_var[k] = static_cast<int>(l.free_keyframes.size());
      l.free_keyframes.push_back(k);
    }
    return l.pose_var[k];
  };
  for (const BundleEdge& e : lp.edges) {
    if (!e.active) continue;
    free_pose(e.keyframe);
    if (point_var[e.point] == kNoBundleVar) {
      point_var[e.point] = static_cast<int>(l.points.size());
      l.points.push_back(e.point);
      count.push_back(0);
    }
    ++count[static_cast<std::size_t>(point_var[e.point])];
  }
  l.point_begin.assign(l.points.size() + 1, 0);
  for (std::size_t v = 0; v < l.points.size(); ++v) l.point_begin[v + 1] = l.point_begin[v] + count[v];
  std::vector<std::size_t> next(l.point_begin.begin(), l.point_begin.end() - 1);
  l.edges.resize(l.point_begin.back());
  l.edge_pose.resize(l.edges.size());
  for (std::size_t i = 0; i < lp.edges.size(); ++i) {
    const BundleEdge& e = lp.edges[i];
    if (!e.active) continue;
    const std::size_t n = next[static_cast<std::size_t>(point_var[e.point])]++;
    l.edges[n] = i;
    l.edge_pose[n] = l.pose_var[e.keyframe];
  }

  // The extra terms' blocks: poses (rotation, translation) or extra blocks.
  if (lp.extra_terms.empty()) {
    l.dim = l.pose_dim();
    return l;
  }
  enum class Kind { kRotation, kTranslation, kExtra };
  std::unordered_map<const double*, std::pair<Kind, std::size_t>> owner;
  for (std::size_t k = 0; k < lp.keyframes.size(); ++k) {
    owner[lp.poses[k].q.data()] = {Kind::kRotation, k};
    owner[lp.poses[k].t.data()] = {Kind::kTranslation, k};
  }
  for (std::size_t i = 0; i < lp.extra_blocks.size(); ++i) owner[lp.extra_blocks[i].values.get()] = {Kind::kExtra, i};
  const auto owner_of = [&](const double* block) {
    const auto it = owner.find(block);
    ORBATLAS_CHECK(it != owner.end(),
                   "bundle Levenberg-Marquardt: an extra term's block is neither a pose nor an "
                   "extra block of the problem");
    return it->second;
  };
  // The terms' free poses join the others first: the extra blocks follow the poses.
  for (const BundleExtraTerm& term : lp.extra_terms)
    for (const double* block : term.blocks)
      if (const auto [kind, index] = owner_of(block); kind != Kind::kExtra) free_pose(index);
  l.dim = l.pose_dim();
  std::vector<int> extra_offset(lp.extra_blocks.size(), kNoBundleVar);
  l.terms.resize(lp.extra_terms.size());
  for (std::size_t t = 0; t < lp.extra_terms.size(); ++t) {
    for (const double* block : lp.extra_terms[t].blocks) {
      BundleTermBlock tb;
      const auto [kind, index] = owner_of(block);
      if (kind == Kind::kExtra) {
        const BundleExtraBlock& b = lp.extra_blocks[index];
        tb.size = tb.global = b.size;
        if (!b.fixed) {
          if (extra_offset[index] == kNoBundleVar) {
            extra_offset[index] = static_cast<int>(l.dim);
            l.dim += b.size;
            l.free_extras.push_back(index);
            l.extra_offset.push_back(extra_offset[index]);
          }
          tb.offset = extra_offset[index];
        }
      } else {
        tb.size = 3;
        tb.global = kind == Kind::kRotation ? 4 : 3;
        if (const int f = l.pose_var[index]; f != kNoBundleVar) {
          tb.offset = 6 * f + (kind == Kind::kRotation ? 0 : 3);
          if (kind == Kind::kRotation) tb.rotation_of = f;
        }
      }
      l.terms[t].push_back(tb);
    }
  }
  return l;
}

}  // namespace orbatlas
