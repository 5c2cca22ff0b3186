#pragma once
// The writes of a shared map, without a transport: Observe (which frames merge: those with a pose,
// and those without one that relocalize on the map's confirmed trees; then their merge as one new
// version) and RemoveSource. Both run under exactly-once (server/app/exactly_once.h); the merge
// itself (server/app/map_merger.h) runs inside the store's write transaction.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/merging/map_merge.h"
#include "algorithms/relocalization/relocalizer.h"
#include "server/app/exactly_once.h"
#include "server/app/map_index_cache.h"
#include "server/app/map_merger.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct SharedMapOptions {
  algorithms::RelocalizerOptions relocalizer;  // for frames without a pose
  algorithms::MergeOptions merge;
  // Rebuild the connected components of observations the frames join after merging them
  // (algorithms::RebuildTrees, server/app/merge_region.h): the map is then a function of the set
  // of observations, and concurrent drones give the map a sequential upload gives. False keeps
  // the incremental, order-dependent merge.
  bool consolidate = true;
  // The evidence of absence (server/app/absence_ledger.h): which trees each frame should have
  // seen, and the removal of trees that are gone. Unset: detections are merged only.
  std::optional<AbsenceSettings> absence = AbsenceSettings{};
};

// One frame of an Observe call.
struct ObserveFrame {
  algorithms::FrameObservations observations;  // its map_from_sensor is the pose, when it has one
  bool has_pose = false;                       // false: relocalized in the map first
  std::optional<Eigen::Vector3d> gravity;      // sensor frame, unit: for that relocalization
  PoseSigma pose_sigma;  // of a given pose (0: exact); a relocalized one has its own
};

struct ObserveCall {
  WriteCall write;  // request id, "Observe", deadline
  std::string map_name;
  std::string source;
  // Set: refuse the call (ServiceError kAborted) unless the map is at this version.
  std::optional<int64_t> base_version;
  std::vector<ObserveFrame> frames;
  // The sensor as the caller states it, for the evidence of absence: horizontal range (m) and
  // detection probability near the sensor; 0: learned from the frames.
  double sensor_range = 0;
  double detection_probability = 0;
  bool merge_only = false;  // no evidence of absence (ObserveRequest.merge_only)
};

// What became of one frame.
struct FrameOutcome {
  int64_t frame_id = 0;
  bool merged = false;       // false: skipped, `detail` says why
  bool relocalized = false;  // its pose came from relocalization
  std::string detail;
  Eigen::Isometry3d map_from_sensor = Eigen::Isometry3d::Identity();  // of a merged frame
  PoseSigma pose_sigma;                                               // of a merged frame
  FrameMergeCounts counts;                                            // of a merged frame
};

struct ObserveOutcome {
  std::vector<FrameOutcome> frames;  // one per frame of the call, in order
  storage::MapInfo map;              // the map after the call
  bool cancelled = false;            // the caller gave up before the merge: nothing was written
};

// Observe: merges `call.frames` into the map and weighs their evidence of absence (frames with a
// pose and no trees give evidence only). `encode(outcome)` gives the bytes of the answer
// stored with the write for the request id (`outcome.map` then is the map the write leaves);
// `cancelled` is asked before each frame. A frame that cannot be placed (no pose and no
// relocalization) is skipped, not an error. Throws ValidationError (request id), storage errors
// (unknown map, ...) and ServiceError kAborted for a stale base version.
Written<ObserveOutcome> ApplyObserve(
    storage::MapStore& store, MapIndexCache& index_cache, const ObserveCall& call,
    const SharedMapOptions& options,
    const std::function<std::string(const ObserveOutcome&)>& encode,
    const std::function<bool()>& cancelled);

struct SourceRemovalOutcome {
  storage::MapInfo map;  // the map after the removal
  int64_t observations_removed = 0;
  int64_t trees_updated = 0;
  int64_t trees_removed = 0;
};

// Removes every observation of `source` from `map` as one new version (RemoveSourceChanges);
// `encode` as for Observe. Throws ServiceError kNotFound when the map has no observation of it.
Written<SourceRemovalOutcome> ApplyRemoveSource(
    storage::MapStore& store, const WriteCall& call, const std::string& map,
    const std::string& source, const algorithms::MergeOptions& options,
    const std::function<std::string(const SourceRemovalOutcome&)>& encode);

}  // namespace forestmap::server
