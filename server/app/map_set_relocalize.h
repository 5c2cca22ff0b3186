#pragma once
// One relocalization question over many maps (a district of plot maps, whichever the sensor is
// in): which maps may hold the sensor, one search per frame (maps sharing a CRS searched at once
// in the index of their union, map_union.h; a map without CRS alone), each search with the other
// searches' area counted in its look-elsewhere test (RelocalizeQuery::other_search_area), and one
// answer from theirs.
//
// A union's answer names the map holding most of its matched trees; each match names its own
// map. The question's answer: LOCALIZED when one search localizes the view, or several do at the
// same pose (the one whose coverage holds the sensor's position answers, else the one with the
// most inliers); AMBIGUOUS when two localize it at poses that disagree, or when one localizes it
// and another is ambiguous itself; AMBIGUOUS as a search answered when none localizes it and one
// is ambiguous; else NOT_FOUND, reported as the search with the most inliers answered. Indexes
// come from the server's MapIndexCache as the question needs them.

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
// has a prior, those that MayHoldSensor at its ViewRange, and every map sharing a CRS with one
// that does (their union is searched within the prior; one union for every prior). In the order
// given.
std::vector<storage::MapInfo> CandidateMaps(const std::vector<storage::MapInfo>& maps,
                                            const algorithms::RelocalizeQuery& query,
                                            const algorithms::RelocalizerOptions& options);

// A map named alone: RelocalizeInMaps needs no more of a question's only map than its name.
storage::MapInfo MapNamed(const std::string& name);

// The searches a question over `maps` runs: one per CRS shared by maps, one per map without.
size_t SearchCount(const std::vector<storage::MapInfo>& maps);

struct MapAnswer {
  std::string map;  // the map answering: of a union, the one holding most of the matched trees
  // The index searched (a union's, or the map's own) and the answering map's version.
  MapIndexCache::Entry entry;
  algorithms::RelocalizeResult result;  // of this search, counting the others'; ids of own maps
  std::vector<std::string> match_maps;  // of a union: each of result.matches' map; else empty
  double search_area = 0;  // m^2, QuerySearchArea of the query in this search (0 when alone)
};

struct MapSetAnswer {
  std::vector<MapAnswer> answers;  // one per search, in the order of their first maps
  // The answer the question reports (none when no map was searched) and, when two maps
  // disagree, the other map's answer.
  std::optional<size_t> reported;
  std::optional<size_t> rival;
  algorithms::RelocalizeResult result;  // the question's: answers[*reported]'s, or AMBIGUOUS
};

// Runs `query` in `maps` (indexes from `cache`: throws what MapIndexCache::Get and
// MapUnionCache::Get throw) and decides the question's answer (see the top of this file). A map
// alone needs only its name. An empty `maps` answers NOT_FOUND, reason kOutsidePrior when the
// query has a prior, else kNoMatchingConstellation.
MapSetAnswer RelocalizeInMaps(MapIndexCache& cache, const std::vector<storage::MapInfo>& maps,
                              const algorithms::RelocalizeQuery& query,
                              const algorithms::RelocalizerOptions& options);

}  // namespace forestmap::server
