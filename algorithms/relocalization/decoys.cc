#include "algorithms/relocalization/decoys.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

namespace forestmap::algorithms {
namespace {

constexpr size_t kNeighbours = 12;      // map trees around an anchor's match (two lattice rings)
constexpr int kTurns = 12;              // headings: multiples of 30 degrees
constexpr size_t kPatternAnchors = 3;   // matched query trees whose neighbourhoods give the rate
constexpr double kGateFromRmse = 3.0;   // comparison gate = this x the pose's rmse ...
constexpr double kMinGateShare = 0.35;  // ... within [this share, 1] x inlier_distance
constexpr double kMinHitShare = 0.5;    // a decoy must hit this share of the pose's hits
// A pose fitting within this share of the inlier distance (gate) is told from a shifted
// pattern by its residuals, not its inlier count.
constexpr double kTightGateShare = 0.7;
// A stand counts as regular when poses aligned to its pattern hit this many times as often as
// random ones (a grid: 3-20 times; a natural forest: about once).
constexpr double kRegularFactor = 1.5;

// Hits of a pose on the occupancy grid among the `count` nearest query trees, stopping once
// `needed` is out of reach.
int Hits(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose, size_t count,
         int needed) {
  int hits = 0;
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  for (size_t i = 0; i < count; ++i) {
    const Eigen::Vector2d& p = q.xy[i];
    hits += m.occupancy->Near(c * p.x() - s * p.y() + pose.translation.x(),
                              s * p.x() + c * p.y() + pose.translation.y());
    if (hits + static_cast<int>(count - i - 1) < needed) return hits;
  }
  return hits;
}

// Adds to `turn_hits`, per heading, the mean hits of the decoys that put `anchor`'s query tree
// on each map tree around its match (the pose itself excluded).
void AddTurnHits(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                 const Association& anchor, size_t nearest, std::vector<double>* turn_hits) {
  const auto around = m.positions->Knn(m.positions->point(anchor.map), kNeighbours + 1);
  for (const auto& [j, d2] : around) {
    for (int turn = 0; turn < kTurns; ++turn) {
      if (j == anchor.map && turn == 0) continue;
      Rigid2 decoy{WrapAngle(pose.yaw + turn * 2 * M_PI / kTurns), {0, 0}};
      decoy.translation = m.Xy(j) - decoy(q.xy[anchor.query]);
      const int hits = Hits(m, q, decoy, nearest, 0);
      (*turn_hits)[turn] += (hits - 1.0) / (turn == 0 ? around.size() - 1 : around.size());
    }
  }
}

// Whether two poses differ by more than the comparison can blur (a decoy that fell back onto
// the pose is the pose).
bool Apart(const Rigid2& a, const Rigid2& b, const RelocalizerOptions& options) {
  return (a.translation - b.translation).norm() > 2 * options.inlier_distance ||
         std::abs(WrapAngle(a.yaw - b.yaw)) > 0.5 * options.distinct_yaw;
}

uint64_t Cell(const Rigid2& pose, double size) {
  const auto cx = static_cast<int64_t>(std::floor(pose.translation.x() / size));
  const auto cy = static_cast<int64_t>(std::floor(pose.translation.y() / size));
  const auto cyaw = static_cast<int64_t>(std::floor((pose.yaw + M_PI) / 0.05));
  return (static_cast<uint64_t>(cx & 0xFFFFFF) << 40) |
         (static_cast<uint64_t>(cy & 0xFFFFFF) << 16) | static_cast<uint64_t>(cyaw & 0xFFFF);
}

}  // namespace

DecoyTest TestDecoys(const MapIndexImpl& m, const LevelledQuery& q, const Hypothesis& pose,
                     const RelocalizerOptions& options) {
  DecoyTest test;
  test.gate = std::clamp(kGateFromRmse * pose.rmse, kMinGateShare * options.inlier_distance,
                         options.inlier_distance);
  const size_t nearest = ScoringPrefix(m, q, pose.pose, options.quick_score_trees);
  Hypothesis scored = pose;
  Score(m, q, options, &scored, test.gate, nearest);
  test.pose_score = scored.score;
  const int needed =
      std::max(3, static_cast<int>(std::ceil(kMinHitShare * Hits(m, q, pose.pose, nearest, 0))));
  const std::vector<Association> anchors =
      Associate(m, q, pose.pose, options, options.inlier_distance, nearest);
  if (anchors.empty() || nearest < 2) return test;
  // Around the match of the query tree nearest the sensor: every neighbouring map tree, at
  // every heading; the hits of each (its anchor excluded) give the pattern's chance level.
  const Eigen::Vector2d query_xy = q.xy[anchors[0].query];
  const auto around = m.positions->Knn(m.positions->point(anchors[0].map), kNeighbours + 1);
  std::vector<double> turn_hits(kTurns, 0.0);
  std::unordered_set<uint64_t> tried;
  for (const auto& [j, d2] : around) {
    for (int turn = 0; turn < kTurns; ++turn) {
      if (j == anchors[0].map && turn == 0) continue;  // the pose itself
      Hypothesis decoy;
      decoy.pose.yaw = WrapAngle(pose.pose.yaw + turn * 2 * M_PI / kTurns);
      decoy.pose.translation = m.Xy(j) - Rigid2{decoy.pose.yaw, {0, 0}}(query_xy);
      ++test.candidates;
      const int hits = Hits(m, q, decoy.pose, nearest, 0);
      turn_hits[turn] += (hits - 1.0) / (turn == 0 ? around.size() - 1 : around.size());
      if (hits < needed) continue;
      Polish(m, q, options, &decoy, nearest);
      if (!Apart(decoy.pose, pose.pose, options) ||
          !tried.insert(Cell(decoy.pose, options.inlier_distance)).second) {
        continue;
      }
      Score(m, q, options, &decoy, test.gate, nearest);
      if (decoy.score > test.best.score) test.best = decoy;
    }
  }
  // The pattern's rate from more anchors than the first: one anchor's neighbourhood (a gap of
  // dead trees, a false stem's match) can make a plantation look random.
  const size_t pattern_anchors = std::min(anchors.size(), kPatternAnchors);
  for (size_t a = 1; a < pattern_anchors; ++a) {
    AddTurnHits(m, q, pose.pose, anchors[a], nearest, &turn_hits);
  }
  test.pattern_rate = std::max(0.0, *std::max_element(turn_hits.begin(), turn_hits.end())) /
                      static_cast<double>(pattern_anchors * (nearest - 1));
  test.passed = test.pose_score >= options.decoy_ratio * test.best.score;
  return test;
}

PoseBelief Assess(const MapIndexImpl& m, const LevelledQuery& q, const Hypothesis& pose,
                  const SearchExtent& extent, const RelocalizerOptions& options,
                  const DecoyTest* decoys) {
  PoseBelief belief;
  belief.decoys = decoys ? *decoys : TestDecoys(m, q, pose, options);
  // Regularity: how much more often poses aligned to the local pattern hit than random ones,
  // on the same nearest trees. It scales the random-forest chance, but only where the stand is
  // clearly regular (a natural forest's best heading hits a little more often than average).
  const size_t nearest = ScoringPrefix(m, q, pose.pose, options.quick_score_trees);
  double random_near = 0;
  for (size_t i = 0; i < nearest; ++i) random_near += m.ChanceAt(pose.pose(q.xy[i]));
  const double regularity =
      random_near > 0 ? belief.decoys.pattern_rate * nearest / random_near : 1.0;
  const double random_chance = ChanceInliers(m, q, pose.pose);
  belief.regular = regularity > kRegularFactor;
  belief.chance = belief.regular ? regularity * random_chance : random_chance;
  belief.tight = belief.decoys.gate <= kTightGateShare * options.inlier_distance;
  const double scale = belief.regular ? regularity : 1.0;
  belief.test = TestSignificance(m, q, pose.pose, extent, scale, options);
  if (!belief.test.significant && belief.tight && belief.regular) {
    belief.test = TestSignificance(m, q, pose.pose, extent, 1.0, options);
  }
  belief.significant = belief.test.significant;
  return belief;
}

}  // namespace forestmap::algorithms
