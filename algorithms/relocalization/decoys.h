#pragma once
// Internal to the relocalizer: the chance level of a pose from the local pattern of the map.
//
// A random (Poisson) forest rarely matches a shifted or turned copy of a query, but a regular
// stand (a plantation's grid, rows) does: shifted by one spacing or turned by the grid's
// symmetry, a query lands on trees again. The decoys of a pose are such alternatives, made from
// the map around it: the query moved so that one of its matched trees lands on a neighbouring
// map tree, at the same heading and turned by multiples of 30 degrees (every lattice symmetry:
// 60, 90, 180 degrees), each polished by one least-squares step. The pose is believable only
// when it explains the query clearly better than its best decoy, at a gate scaled to its own
// residuals: where detection noise is smaller than the planting error, the true pose fits
// tightly and a shifted grid does not.

#include "algorithms/relocalization/pose_search.h"
#include "algorithms/relocalization/significance.h"

namespace forestmap::algorithms {

DecoyTest TestDecoys(const MapIndexImpl& m, const LevelledQuery& q, const Hypothesis& pose,
                     const RelocalizerOptions& options);

struct PoseBelief {
  DecoyTest decoys;
  double chance = 0;         // inliers expected by chance: random forest or local pattern
  bool tight = false;        // the pose fits much more tightly than the inlier gate
  bool regular = false;      // the local pattern is regular (a plantation's grid, rows)
  bool significant = false;  // see Assess
  GateSignificance test;     // the significance test that decided
  bool believable() const { return significant && decoys.passed; }
};

// Whether a refined pose is believable: its inliers are significant against the larger of the
// random-forest chance (ChanceInliers) and the local pattern's (pattern_rate x query trees), or,
// when it fits much more tightly than the inlier gate, against the random-forest chance alone;
// and it beats its best decoy. `extent`: what the search looked at (the look-elsewhere
// effect, significance.h).
// `decoys`: the decoy test of this very pose when already done (the search's last one).
PoseBelief Assess(const MapIndexImpl& m, const LevelledQuery& q, const Hypothesis& pose,
                  const SearchExtent& extent, const RelocalizerOptions& options,
                  const DecoyTest* decoys = nullptr);

}  // namespace forestmap::algorithms
