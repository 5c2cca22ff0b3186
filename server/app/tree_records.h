#pragma once
// Stored rows (storage::) as the algorithms see them, and back. Unknown z and DBH are
// std::nullopt in storage and NaN (algorithms::kUnknown) in algorithms, both ways.

#include <map>
#include <set>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/polygon.h"
#include "algorithms/merging/map_merge.h"
#include "storage/map_store.h"

namespace forestmap::server {

// A stored tree as the relocalizer sees it. Requires tree.id.
algorithms::MapTree ToMapTree(const storage::TreeRecord& tree);

// A stored survey boundary as the map index takes it (map frame, m; empty: none).
std::vector<algorithms::Polygon> ToPolygons(const storage::Boundary& boundary);

// Observation rows.
algorithms::TreeObservation ToTreeObservation(const storage::ObservationRecord& record);
storage::ObservationRecord ToObservationRecord(const algorithms::TreeObservation& observation);

// A merged tree as a stored row; `attributes` and `null_attributes` are the survey columns it
// keeps.
storage::TreeRecord ToTreeRecord(const algorithms::TreeEstimate& tree,
                                 const std::map<std::string, std::string>& attributes,
                                 const std::set<std::string>& null_attributes = {});

}  // namespace forestmap::server
