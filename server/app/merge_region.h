#pragma once
// The part of a shared map that a merge rebuilds. The map is a pure function of the set of its
// observation rows, computed per connected component of the rows (algorithms::RebuildTrees), so
// a merge that adds rows must rebuild exactly the components those rows join, whole: a fixpoint
// that loads the current rows cell by cell (storage::ObservationCell) around the seed rows and
// around every row linked to them, until no loaded component touching a seed has a row whose
// neighbourhood is not loaded yet. Other components keep their trees, which is why any order or
// batching of the same uploads ends in the same map.

#include <cstdint>
#include <map>
#include <span>
#include <vector>

#include "algorithms/merging/map_merge.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct MergeRegion {
  // Current rows of the components that the seeds join, by id of the row.
  std::vector<storage::ObservationRecord> rows;
  // The trees of those rows, and surveyed trees without rows (never observed yet) that stand in
  // those components, by id.
  std::map<int64_t, storage::TreeRecord> trees;
  // The survey prior (algorithms::SurveyObservation) of each such tree without rows: a row of
  // the map too, stored once its tree changes.
  std::vector<algorithms::TreeObservation> unsaved_priors;
  int iterations = 0;  // load rounds until the fixpoint
  // Trees outside the region with at least options.fold_rows rows, all of them loaded with it
  // (neighbours in its cells), and those rows: a merge folds them (server/app/map_merger.h), so
  // that the next one around reads their summaries.
  std::map<int64_t, std::vector<storage::ObservationRecord>> foldable_outside;
};

// Loads the region of `seeds` (rows to be merged, in the map frame; their tree ids are ignored).
// The region also holds every row of a tree that has a row in it (trees written before this
// rule, or split by a source removal, may span components), and then those rows' components:
// it is always a union of whole components, as RebuildTrees needs.
MergeRegion LoadMergeRegion(storage::MergeReader& reader,
                            std::span<const algorithms::TreeObservation> seeds,
                            const algorithms::MergeOptions& options);

}  // namespace forestmap::server
