#pragma once
// The merge steps of Observe and RemoveSource: pure functions of what a storage::MergeReader
// shows (the map's current version, read inside the store's write transaction) that return the
// storage::MapChanges to commit as the next version. The map's trees are a pure function of the
// set of its observation rows, component by component (algorithms::RebuildTrees); a change
// rebuilds the components it touches (server/app/merge_region.h), so nothing but rows and derived
// fields is persisted. A surveyed tree without rows gets its survey prior
// (algorithms::SurveyObservation) as its first row when first touched.
//
// Folding bounds what a change reads: once a tree the rebuild went through keeps
// MergeOptions::fold_rows stored rows, they are folded into one summary row of the tree
// (algorithms::SummaryObservation, a sufficient statistic of them), which later merges read in
// their place. Folded rows stay in the map with their sources (storage::ObservationRecord::
// folded), so a source's removal takes them out and makes the summary again from the rest, and
// every version keeps which rows its summaries stand for. A merge then reads about fold_rows
// rows per tree whatever the tree's history; the association of folded rows is fixed from then
// on (docs/design.md, "Shared maps: merging observations").

#include <cstdint>
#include <string>
#include <vector>

#include "algorithms/merging/map_merge.h"
#include "server/app/absence_ledger.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct FrameMergeCounts {
  int associated = 0;  // detections that updated an existing tree
  int added = 0;       // detections that started a new candidate
  int promoted = 0;    // candidates confirmed by this frame
  int ignored = 0;     // detections not merged (range, invalid)
  int missed = 0;      // trees the frame should have seen and did not (evidence of absence)
  int removed = 0;     // trees its evidence showed gone (removed or retired)
};

struct FramesMerge {
  std::vector<FrameMergeCounts> counts;  // per input frame
  storage::MapChanges changes;
};

// Merges `frames` (map_from_sensor set) in order into the trees of the region their detections
// join (server/app/merge_region.h), for the per-frame counts. With `consolidate`, the region, whole
// connected components of the map's rows, is then rebuilt from its rows and the new ones
// (algorithms::RebuildTrees), so that the map is a pure function of the set of observations it
// received: concurrent requests, in any order and batches, give the map one sequential upload
// gives. Without, the incremental merge is kept (order-dependent). With a `ledger`, each frame
// (with trees or none) also weighs the evidence of absence of the live trees near its sensor
// before its detections merge; the trees it shows gone leave the merge and the map
// (server/app/absence_ledger.h).
FramesMerge MergeFrames(storage::MergeReader& reader,
                        const std::vector<algorithms::FrameObservations>& frames,
                        const algorithms::MergeOptions& options, bool consolidate,
                        AbsenceLedger* ledger = nullptr);

struct SourceRemoval {
  storage::MapChanges changes;
  int64_t trees_updated = 0;
  int64_t trees_removed = 0;
};

// Drops every current observation of `source` and rebuilds the connected components they were
// in from the remaining rows (as MergeFrames does), so the map stays the pure function of the
// set of observations it holds; trees left without rows are removed. Throws ServiceError
// kNotFound when the source has no observation in the map.
SourceRemoval RemoveSourceChanges(storage::MergeReader& reader, const std::string& source,
                                  const algorithms::MergeOptions& options);

}  // namespace forestmap::server
