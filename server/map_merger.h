#pragma once
// The merge steps of Observe and RemoveSource: pure functions of what a storage::MergeReader
// shows (the map's current version, read inside the store's write transaction) that return the
// storage::MapChanges to commit as the next version. Tree state is rebuilt from the stored
// observation rows (algorithms::EstimateFromObservations: a tree is a pure function of its
// observations), so nothing but rows and derived fields is persisted. A surveyed tree without
// rows gets its survey prior (algorithms::SurveyObservation) as its first row when first touched.

#include <cstdint>
#include <string>
#include <vector>

#include "algorithms/map_merge.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct FrameMergeCounts {
  int associated = 0;  // detections that updated an existing tree
  int added = 0;       // detections that started a new candidate
  int promoted = 0;    // candidates confirmed by this frame
  int ignored = 0;     // detections not merged (range, invalid)
};

struct FramesMerge {
  std::vector<FrameMergeCounts> counts;  // per input frame
  storage::MapChanges changes;
};

// Merges `frames` (map_from_sensor set) in order into the trees around them. With
// `consolidate`, the rows of every tree around the frames are then re-associated afresh in
// canonical order and duplicate trees merged (algorithms::RebuildTrees), so that the map depends
// on which observations a region holds rather than on the order in which concurrent requests
// arrived.
FramesMerge MergeFrames(storage::MergeReader& reader,
                        const std::vector<algorithms::FrameObservations>& frames,
                        const algorithms::MergeOptions& options, bool consolidate);

struct SourceRemoval {
  storage::MapChanges changes;
  int64_t trees_updated = 0;
  int64_t trees_removed = 0;
};

// Drops every current observation of `source` and recomputes the trees they belonged to from
// their remaining rows; trees left without rows are removed. Throws ServiceError NOT_FOUND when
// the source has no observation in the map.
SourceRemoval RemoveSourceChanges(storage::MergeReader& reader, const std::string& source,
                                  const algorithms::MergeOptions& options);

}  // namespace forestmap::server
