#pragma once
// One relocalization question over many maps (a district of plot maps, whichever the sensor is
// in): which maps may hold the sensor, each searched with the other maps' area counted in its
// look-elsewhere test (RelocalizeQuery::other_search_area), and one answer from theirs.
//
// The answer: LOCALIZED when one map localizes the view, or several do at the same pose (maps of
// one frame that overlap, or a view across a plot boundary; the one whose coverage holds the
// sensor's position answers, else the one with the most inliers); AMBIGUOUS when two maps
// localize it at poses that disagree, or when a map localizes it and another is ambiguous
// itself; AMBIGUOUS as a map answered when none localizes it and one is ambiguous; else
// NOT_FOUND, reported as the map with the most inliers answered. Indexes come from the server's
// MapIndexCache, one map at a time as the question needs them.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/relocalization/relocalizer.h"
#include "server/app/map_index_cache.h"
#include "storage/map_store.h"

namespace forestmap::server {

// m: the farthest (horizontally) that a query tree the relocalizer uses can be from the sensor,
// whatever the sensor's tilt: the largest distance of a detected tree, at most max_query_range.
double ViewRange(const algorithms::RelocalizeQuery& query,
                 const algorithms::RelocalizerOptions& options);

// Whether a sensor within `prior`'s disc may see the trees of a map spanning `extent` from up to
// `range` away (the extent grown by the range meets the disc).
bool MayHoldSensor(const storage::Extent& extent, const algorithms::PriorPose& prior, double range);

// Of `maps`, those a question may find the sensor in: with confirmed trees, and when the query
// has a prior, those that MayHoldSensor at its ViewRange. In the order given.
std::vector<std::string> CandidateMaps(const std::vector<storage::MapInfo>& maps,
                                       const algorithms::RelocalizeQuery& query,
                                       const algorithms::RelocalizerOptions& options);

struct MapAnswer {
  std::string map;
  MapIndexCache::Entry entry;
  algorithms::RelocalizeResult result;  // of this map alone, its search counting the others'
  double search_area = 0;  // m^2, QuerySearchArea of the query in this map (0 when alone)
};

struct MapSetAnswer {
  std::vector<MapAnswer> answers;  // one per map searched, in the order given
  // The answer the question reports (none when no map was searched) and, when two maps
  // disagree, the other map's answer.
  std::optional<size_t> reported;
  std::optional<size_t> rival;
  algorithms::RelocalizeResult result;  // the question's: answers[*reported]'s, or AMBIGUOUS
};

// Runs `query` in each of `maps` (indexes from `cache`: throws what MapIndexCache::Get throws) and
// decides the question's answer (see the top of this file). An empty `maps` answers NOT_FOUND,
// reason kOutsidePrior when the query has a prior, else kNoMatchingConstellation.
MapSetAnswer RelocalizeInMaps(MapIndexCache& cache, const std::vector<std::string>& maps,
                              const algorithms::RelocalizeQuery& query,
                              const algorithms::RelocalizerOptions& options);

}  // namespace forestmap::server
