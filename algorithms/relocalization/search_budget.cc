#include "algorithms/relocalization/search_budget.h"

#include <algorithm>
#include <cmath>

namespace forestmap::algorithms {

int StrongInliers(const LevelledQuery& q, const RelocalizerOptions& options) {
  return StrongInliers(RatioTrees(q, options), options);
}

int StrongInliers(int nearest, const RelocalizerOptions& options) {
  const int share = static_cast<int>(options.decisive_fraction * nearest);
  // Twice min_inliers, unless the query is too small to show that many beside its share.
  const int wanted = std::min(2 * options.min_inliers, std::max(share, nearest / 2));
  return std::max({options.min_inliers, share, wanted});
}

int PolishHits(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose, int base,
               const RelocalizerOptions& options, int trees) {
  constexpr double kPolishSigmas = 3.0;
  const double nearest =
      static_cast<double>(std::min<size_t>(q.xy.size(), options.quick_score_trees));
  const double n = trees >= 0 ? std::min<double>(trees, nearest) : nearest;
  const double p0 = m.occupancy->OccupiedFractionAt(pose.translation.x(), pose.translation.y());
  const double chance = n * p0 + kPolishSigmas * std::sqrt(n * p0 * (1 - p0));
  return std::max(base, static_cast<int>(std::ceil(chance)));
}

}  // namespace forestmap::algorithms
