#pragma once
// Internal to the pose search: when a search may stop early.

#include "algorithms/relocalization/pose_search.h"

namespace forestmap::algorithms {

// Inliers among the RatioTrees nearest query trees that decide the search (it ends a few
// triangles later): options.decisive_fraction of them, and twice options.min_inliers where the
// query holds that many trees. A view of a sparse stand holds 10-15 trees, some of them false
// or missed in the map: requiring 12 there made every such search run through all its
// triangles (the 1,000,000-tree mosaic: up to 650,000 poses checked, 100 ms and more).
int StrongInliers(const LevelledQuery& q, const RelocalizerOptions& options);
// The same for `nearby` nearest trees (those inside the map's coverage under a pose).
int StrongInliers(int nearby, const RelocalizerOptions& options);

// Bitmap hits among the quick_score_trees nearest query trees a pose needs to be polished and
// scored: `base`, and well above what chance gives where it lies (kPolishSigmas binomial
// deviations over the local occupied share). In a dense stand a quarter of the cells are near a
// tree, so a random pose already hits 7 of 30; polishing all of those used up the search's
// max_scored_hypotheses before the true pose's triangle came up.
// `trees`: how many of those nearest trees lie inside the map's coverage under the pose (< 0:
// all of them); the others cannot hit.
int PolishHits(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose, int base,
               const RelocalizerOptions& options, int trees = -1);

}  // namespace forestmap::algorithms
