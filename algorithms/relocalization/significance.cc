#include "algorithms/relocalization/significance.h"

#include <algorithm>
#include <cmath>

namespace forestmap::algorithms {
namespace {

constexpr double kGates[] = {1.0, 0.7, 0.5, 0.35};  // x options.inlier_distance
constexpr double kMaxOccupied = 0.95;               // occupied share beyond which density saturates
constexpr double kMinLeverArm = 2.0;                // m, floor of the query's RMS range
// Share of the nearby query trees a true pose explains at a gate that holds its residuals
// (simulated views: ~0.8 with 20% false stems; the real sequences: 0.6 and more).
constexpr double kTrueShare = 0.75;

// Independent pose cells in `extent` at gate g: squares of side 2 g, headings that move the
// query's trees (at their RMS range) by 2 g apart; at least the poses tried.
double PoseCells(const SearchExtent& extent, double gate, double rms_range) {
  const double positions = extent.area / (4 * gate * gate);
  const double headings = std::max(1.0, M_PI * std::max(rms_range, kMinLeverArm) / gate);
  return std::max(static_cast<double>(std::max<int64_t>(extent.poses, 1)), positions * headings);
}

}  // namespace

double SearchArea(const MapIndexImpl& m, const std::optional<PriorPose>& prior, double reach) {
  const double seen = m.coverage->area() + m.coverage->perimeter() * reach + M_PI * reach * reach;
  if (!prior) return seen;
  return std::min(seen, M_PI * prior->radius * prior->radius);
}

GateSignificance TestSignificance(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                                  const SearchExtent& extent, double chance_scale,
                                  const RelocalizerOptions& options) {
  // Only the query trees inside the coverage are evidence: those outside have no chance (0)
  // and do not count among the nearby trees.
  const ViewInCoverage view = InCoverage(m, q, pose, options);
  std::vector<double> occupied(q.xy.size());  // local chance at the occupancy grid's radius
  double sum_range2 = 0;
  int inside = 0;
  for (size_t i = 0; i < q.xy.size(); ++i) {
    occupied[i] = std::min(kMaxOccupied, m.ChanceAt(pose(q.xy[i])));
    if (!view.inside[i]) continue;
    sum_range2 += q.xy[i].squaredNorm();
    ++inside;
  }
  const double rms_range = inside == 0 ? 0 : std::sqrt(sum_range2 / inside);
  const int nearby = view.nearby, prefix = view.prefix;  // as the inlier ratio's
  const double gates = static_cast<double>(std::size(kGates));
  // Every pair within the widest gate, once: each gate counts those within it.
  const std::vector<Association> pairs = Associate(m, q, pose, options, options.inlier_distance);
  GateSignificance best;
  double best_margin = 0;  // of the best gate's log likelihood ratio over its threshold
  for (double share : kGates) {
    GateSignificance test;
    test.gate = share * options.inlier_distance;
    int near = 0;  // inliers among the nearby trees
    for (const Association& a : pairs) {
      if (a.distance > test.gate) continue;
      ++test.inliers;
      near += static_cast<int>(a.query) < prefix;
    }
    double near_chance = 0;  // summed over the nearby trees
    for (size_t i = 0; i < occupied.size(); ++i) {
      const double p = chance_scale * (1 - std::pow(1 - occupied[i], share * share));
      test.chance += p;
      if (static_cast<int>(i) < prefix) near_chance += p;
    }
    // The Poisson tail over the poses tried (each was scored as it is), the likelihood ratio
    // over every pose cell searched (the best of each was found by refinement).
    const double tried = std::max<int64_t>(extent.poses, 1);
    test.p = gates * tried * PoissonTail(test.inliers, test.chance);
    test.trials = gates * PoseCells(extent, test.gate, rms_range);
    // The nearby trees the pose leaves unexplained count against it: the likelihood ratio of
    // "a true pose explaining kTrueShare of them" to "chance" must beat the trials too.
    test.nearby = nearby;
    test.nearby_inliers = near;
    const double p_near = std::min(kMaxOccupied, near_chance / std::max(nearby, 1));
    test.log_ratio = p_near >= kTrueShare
                         ? 0.0
                         : near * std::log(kTrueShare / p_near) +
                               (nearby - near) * std::log((1 - kTrueShare) / (1 - p_near));
    test.significant =
        test.inliers >= test.chance + options.chance_sigmas * std::sqrt(test.chance) &&
        test.p <= options.false_alarm &&
        test.log_ratio >= std::log(test.trials / options.false_alarm);
    const double margin = test.log_ratio - std::log(test.trials / options.false_alarm);
    if (share == kGates[0] || test.significant > best.significant ||
        (test.significant == best.significant && margin > best_margin)) {
      best_margin = margin;
      best = test;
    }
  }
  return best;
}

}  // namespace forestmap::algorithms
