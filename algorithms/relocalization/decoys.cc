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
// random ones (a grid: 3-20 times; a natural forest: about once) ...
constexpr double kRegularFactor = 1.5;
// ... and that many hits at the best of the kTurns headings would come from a random forest
// with at most this probability: a sparse view's decoys make a few hundred tries at chances of
// 1-2%, and the best of kTurns small Poisson counts is no pattern; a grid's shifted copies land
// on trees again and again.
constexpr double kRegularFalseAlarm = 1e-3;

// Per heading: hits of the decoys' query trees (beyond their anchors) and query trees tried.
struct TurnHits {
  std::vector<int> hits = std::vector<int>(kTurns, 0);
  std::vector<int> tries = std::vector<int>(kTurns, 0);
  void Add(int turn, int decoy_hits, size_t nearest) {
    hits[turn] += decoy_hits;
    tries[turn] += static_cast<int>(nearest) - 1;
  }
};

// Hits of a pose on the occupancy grid among the `count` nearest query trees.
int Hits(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose, size_t count) {
  int hits = 0;
  for (size_t i = 0; i < count; ++i) {
    const Eigen::Vector2d p = pose(q.xy[i]);
    hits += m.occupancy->Near(p.x(), p.y());
  }
  return hits;
}

// The hits of a decoy that puts `anchor`'s query tree on another map tree: all of them, and
// those that say something of the pattern: beyond the anchor itself and beyond a query tree
// landing on the anchor's own match (turned half a circle about the midpoint of two matched
// trees, a decoy swaps them whatever the stand: sparse natural stands looked five times as
// regular as they are).
struct DecoyHits {
  int all = 0;
  int pattern = 0;
};
DecoyHits HitsOfDecoy(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& decoy,
                      const Association& anchor, size_t count) {
  const Eigen::Vector2d own = m.Xy(anchor.map);
  const double r2 = m.occupancy->radius() * m.occupancy->radius();
  DecoyHits hits;
  for (size_t i = 0; i < count; ++i) {
    const Eigen::Vector2d p = decoy(q.xy[i]);
    if (!m.occupancy->Near(p.x(), p.y())) continue;
    ++hits.all;
    hits.pattern += i != anchor.query && (p - own).squaredNorm() > r2;
  }
  return hits;
}

// Adds to `turn_hits`, per heading, the hits of the decoys that put `anchor`'s query tree on
// each map tree around its match (the pose itself excluded).
void AddTurnHits(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                 const Association& anchor, size_t nearest, TurnHits* turn_hits) {
  const auto around = m.positions->Knn(m.positions->point(anchor.map), kNeighbours + 1);
  for (const auto& [j, d2] : around) {
    for (int turn = 0; turn < kTurns; ++turn) {
      if (j == anchor.map && turn == 0) continue;
      Rigid2 decoy{WrapAngle(pose.yaw + turn * 2 * M_PI / kTurns), {0, 0}};
      decoy.translation = m.Xy(j) - decoy(q.xy[anchor.query]);
      turn_hits->Add(turn, HitsOfDecoy(m, q, decoy, anchor, nearest).pattern, nearest);
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
      std::max(3, static_cast<int>(std::ceil(kMinHitShare * Hits(m, q, pose.pose, nearest))));
  const std::vector<Association> anchors =
      Associate(m, q, pose.pose, options, options.inlier_distance, nearest);
  if (anchors.empty() || nearest < 2) return test;
  // Around the match of the query tree nearest the sensor: every neighbouring map tree, at
  // every heading; the hits of each (its anchor excluded) give the pattern's chance level.
  const Eigen::Vector2d query_xy = q.xy[anchors[0].query];
  const auto around = m.positions->Knn(m.positions->point(anchors[0].map), kNeighbours + 1);
  TurnHits turn_hits;
  std::unordered_set<uint64_t> tried;
  for (const auto& [j, d2] : around) {
    for (int turn = 0; turn < kTurns; ++turn) {
      if (j == anchors[0].map && turn == 0) continue;  // the pose itself
      Hypothesis decoy;
      decoy.pose.yaw = WrapAngle(pose.pose.yaw + turn * 2 * M_PI / kTurns);
      decoy.pose.translation = m.Xy(j) - Rigid2{decoy.pose.yaw, {0, 0}}(query_xy);
      ++test.candidates;
      const DecoyHits hits = HitsOfDecoy(m, q, decoy.pose, anchors[0], nearest);
      turn_hits.Add(turn, hits.pattern, nearest);
      if (hits.all < needed) continue;
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
  for (int turn = 0; turn < kTurns; ++turn) {
    if (turn_hits.tries[turn] == 0) continue;
    const double rate = static_cast<double>(turn_hits.hits[turn]) / turn_hits.tries[turn];
    if (test.pattern_tries == 0 || rate > test.pattern_rate) {
      test.pattern_rate = rate;
      test.pattern_hits = turn_hits.hits[turn];
      test.pattern_tries = turn_hits.tries[turn];
    }
  }
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
  const double random_hits =
      belief.decoys.pattern_tries * random_near / std::max<size_t>(nearest, 1);
  belief.regular =
      regularity > kRegularFactor &&
      kTurns * PoissonTail(belief.decoys.pattern_hits, random_hits) <= kRegularFalseAlarm;
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
