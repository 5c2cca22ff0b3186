#pragma once
// Internal to the relocalizer: is a pose's inlier count more than the best of the search's
// chance coincidences?
//
// A global search does not only score a few thousand poses: it refines the best of them, so
// in effect it looks at every pose of the map's area at the resolution of the inlier gate (the
// look-elsewhere effect). A wrong pose found that way in a sparse or clustered stand explains
// 6-11 of 11-28 query trees where a random pose expects 0.3-1.5 (foreign stem maps): the
// Poisson tail over the poses tried calls that significant. What tells it from a true pose is
// the rest of the nearby trees, which it leaves unexplained: the likelihood ratio of "a true
// pose explains most of them" to "chance" counts both, and must beat the number of pose cells
// searched. The test is made at several gates, each with its own chance level and number of
// cells: a true pose fits within the detection noise, where coincidences are rarer by the
// square of the gate.

#include <cstdint>
#include <optional>

#include "algorithms/relocalization/pose_search.h"

namespace forestmap::algorithms {

// Where the search could have put the sensor.
struct SearchExtent {
  int64_t poses = 0;  // poses tried (the floor of the look-elsewhere count)
  double area = 0;    // m^2 searched; 0: a local search (only `poses` count)
};

// The searched area (m^2): the positions from which a view reaching `reach` (m) sees into the
// map's coverage (its area, plus its perimeter times the reach, plus a disc of the reach: the
// coverage grown by the reach, exactly for a convex one, more for others), or the prior's disc
// when smaller.
double SearchArea(const MapIndexImpl& m, const std::optional<PriorPose>& prior, double reach = 0);

struct GateSignificance {
  double gate = 0;         // m, the gate that decided (the most significant one)
  int inliers = 0;         // query trees within it of a map tree
  double chance = 0;       // inliers expected at random there
  int nearby = 0;          // the nearby query trees inside the coverage (InCoverage) ...
  int nearby_inliers = 0;  // ... and those within the gate of a map tree
  double p = 1;            // poses tried x Poisson tail of the inliers
  double trials = 0;       // independent pose cells searched at that gate (x the gates tried)
  // log likelihood ratio, over the nearby trees (RatioTrees), of a true pose's share of inliers
  // (most of them) to chance's: must exceed log(trials / options.false_alarm)
  double log_ratio = 0;
  bool significant = false;
};

// Tests `pose` at gates of 1, 0.7, 0.5 and 0.35 x options.inlier_distance: significant at a
// gate when its inliers exceed `chance_scale` x the random chance by options.chance_sigmas
// Poisson sigmas, p <= options.false_alarm and the likelihood ratio beats the pose cells
// searched at options.false_alarm. Returns the most significant gate's test.
GateSignificance TestSignificance(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                                  const SearchExtent& extent, double chance_scale,
                                  const RelocalizerOptions& options);

}  // namespace forestmap::algorithms
