#pragma once
// Internal to the relocalizer: the headings a tracked frame is tried at besides its guess.

#include <Eigen/Core>
#include <vector>

#include "algorithms/relocalization/map_index_internal.h"
#include "algorithms/relocalization/pose_search.h"

namespace forestmap::algorithms {

// Sensor headings that align the query's bearings with the map's as seen from `at` (kd
// coordinates): every query tree and map tree at about the same range vote for the heading that
// puts one on the other; returns the centres of the `count` strongest separated bins.
std::vector<double> HeadingPeaks(const MapIndexImpl& m, const LevelledQuery& q,
                                 const Eigen::Vector2d& at, int count);

}  // namespace forestmap::algorithms
