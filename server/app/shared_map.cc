#include "server/app/shared_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "server/app/limits.h"

namespace forestmap::server {
namespace {

ServiceError Stale(const std::string& name, int64_t current, int64_t base) {
  return ServiceError(ErrorCode::kAborted,
                      "map '" + name + "' is at version " + std::to_string(current) +
                          ", not at the base version " + std::to_string(base) +
                          " (rejected as stale; fetch the map and retry, or merge anyway)");
}

FrameOutcome Skipped(const std::string& detail) {
  FrameOutcome outcome;
  outcome.detail = detail;
  return outcome;
}

// The pose of a frame without one, relocalized on the cached index of the map's confirmed trees
// (current version); a skipped outcome when it is not LOCALIZED.
FrameOutcome Relocalized(MapIndexCache& index_cache, const std::string& map_name,
                         const ObserveFrame& frame, const algorithms::RelocalizerOptions& options) {
  if (frame.observations.trees.size() < static_cast<size_t>(kMinQueryTrees)) {
    return Skipped("no pose given and fewer than 3 trees to relocalize with");
  }
  MapIndexCache::Entry entry;
  try {
    entry = index_cache.Get(map_name);
  } catch (const PreconditionError& e) {
    return Skipped(std::string("no pose given and the map cannot relocalize: ") + e.what());
  }
  algorithms::RelocalizeQuery query;
  query.trees = frame.observations.trees;
  if (frame.gravity) query.gravity = frame.gravity->normalized();
  const algorithms::RelocalizeResult result = algorithms::Relocalize(*entry.index, query, options);
  if (result.status != algorithms::RelocalizeStatus::kLocalized) {
    return Skipped(std::string("relocalization: ") + algorithms::ToString(result.status) + ": " +
                   result.detail);
  }
  FrameOutcome outcome;
  outcome.merged = true;
  outcome.relocalized = true;
  outcome.map_from_sensor = result.map_from_sensor;
  const Eigen::Matrix<double, 6, 6>& covariance = result.covariance;  // x y z roll pitch yaw
  outcome.pose_sigma.xy = std::sqrt(std::max(0.0, (covariance(0, 0) + covariance(1, 1)) / 2));
  outcome.pose_sigma.yaw = std::sqrt(std::max(0.0, result.covariance(5, 5)));
  return outcome;
}

// Merges `frames` (the merged ones of the call, their outcomes in `merged`) as one new version.
// Returns the stored answer when a concurrent call with the same request id wrote first.
std::optional<std::string> MergeObserved(
    storage::MapStore& store, const ObserveCall& call, const SharedMapOptions& options,
    const std::vector<algorithms::FrameObservations>& frames,
    const std::vector<FrameOutcome*>& merged, ObserveOutcome& outcome,
    const std::function<std::string(const ObserveOutcome&)>& encode) {
  storage::MergeNote note;
  note.kind = storage::VersionKind::kObserve;
  note.source = call.source;
  if (call.base_version) note.expected_version = *call.base_version;
  FramesMerge merge;
  const auto set_counts = [&] {
    for (size_t i = 0; i < merged.size(); ++i) merged[i]->counts = merge.counts[i];
  };
  // The answer stored with the write: the frame outcomes and the map it leaves.
  const auto encode_answer = [&](const storage::MapInfo& info) {
    set_counts();
    ObserveOutcome answer = outcome;
    answer.map = info;
    return encode(answer);
  };
  std::optional<AbsenceLedger> ledger;
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  std::vector<PoseSigma> sigmas;
  for (const FrameOutcome* frame : merged) sigmas.push_back(frame->pose_sigma);
  std::optional<std::string> replayed = WriteExactlyOnce(store, call.write, encode_answer, [&] {
    outcome.map = store.Merge(call.map_name, note, [&](storage::MergeReader& reader) {
      if (options.absence && !call.merge_only) {
        AbsenceSettings settings = *options.absence;
        if (call.sensor_range > 0) settings.absence.range = call.sensor_range;
        if (call.detection_probability > 0) {
          settings.absence.detection_probability = call.detection_probability;
        }
        ledger.emplace(call.source,
                       std::chrono::duration_cast<std::chrono::milliseconds>(now).count(),
                       std::move(settings), sigmas);
      }
      merge = MergeFrames(reader, frames, options.merge, options.consolidate,
                          ledger ? &*ledger : nullptr);
      return merge.changes;
    });
  });
  if (!replayed) set_counts();
  return replayed;
}

}  // namespace

Written<ObserveOutcome> ApplyObserve(
    storage::MapStore& store, MapIndexCache& index_cache, const ObserveCall& call,
    const SharedMapOptions& options,
    const std::function<std::string(const ObserveOutcome&)>& encode,
    const std::function<bool()>& cancelled) {
  ValidateRequestId(call.write.request_id);
  Written<ObserveOutcome> written;
  // A repeated request id: the first answer, before any relocalization or merge.
  if (!call.write.request_id.empty()) {
    written.replayed = StoredAnswer(store, call.write);
    if (written.replayed) return written;
  }
  ObserveOutcome& outcome = written.outcome;
  // Fail fast (unknown map, stale base) before relocalizing; the merge checks again.
  outcome.map = store.GetMap(call.map_name);
  if (call.base_version && outcome.map.version != *call.base_version) {
    throw Stale(call.map_name, outcome.map.version, *call.base_version);
  }
  std::vector<algorithms::FrameObservations> frames;
  outcome.frames.reserve(call.frames.size());
  for (const ObserveFrame& frame : call.frames) {
    if (cancelled()) {
      outcome.cancelled = true;
      return written;
    }
    FrameOutcome placed;
    if (!frame.has_pose) {
      placed = frame.observations.trees.empty()
                   ? Skipped("the frame has neither trees nor a pose")
                   : Relocalized(index_cache, call.map_name, frame, options.relocalizer);
    } else {
      placed.merged = true;
      placed.map_from_sensor = frame.observations.map_from_sensor;
      placed.pose_sigma = frame.pose_sigma;
    }
    placed.frame_id = frame.observations.frame_id;
    if (placed.merged) {
      frames.push_back(frame.observations);
      frames.back().map_from_sensor = placed.map_from_sensor;
    }
    outcome.frames.push_back(std::move(placed));
  }
  std::vector<FrameOutcome*> merged;
  for (FrameOutcome& frame : outcome.frames) {
    if (frame.merged) merged.push_back(&frame);
  }
  if (!frames.empty()) {
    written.replayed = MergeObserved(store, call, options, frames, merged, outcome, encode);
  }
  return written;
}

Written<SourceRemovalOutcome> ApplyRemoveSource(
    storage::MapStore& store, const WriteCall& call, const std::string& map,
    const std::string& source, const algorithms::MergeOptions& options,
    const std::function<std::string(const SourceRemovalOutcome&)>& encode) {
  storage::MergeNote note;
  note.kind = storage::VersionKind::kRemoveSource;
  note.source = source;
  SourceRemoval removal;
  Written<SourceRemovalOutcome> written;
  const auto fill = [&](const storage::MapInfo& info) {
    SourceRemovalOutcome& outcome = written.outcome;
    outcome.map = info;
    outcome.observations_removed =
        static_cast<int64_t>(removal.changes.removed_observations.size());
    outcome.trees_updated = removal.trees_updated;
    outcome.trees_removed = removal.trees_removed;
    return written.outcome;
  };
  written.replayed = WriteExactlyOnce(
      store, call, [&](const storage::MapInfo& info) { return encode(fill(info)); },
      [&] {
        fill(store.Merge(map, note, [&](storage::MergeReader& reader) {
          removal = RemoveSourceChanges(reader, source, options);
          return removal.changes;
        }));
      });
  return written;
}

}  // namespace forestmap::server
