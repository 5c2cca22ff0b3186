// ForestMapService: the bodies of the shared-map RPCs (Observe, RemoveSource). The merge itself
// (server/map_merger.h) runs inside the store's write transaction; relocalization of frames
// without a pose runs before it, on the cached index of the map's confirmed trees.

#include <chrono>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "server/app/exactly_once.h"
#include "server/app/map_merger.h"
#include "server/grpc/convert.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/grpc/validation.h"

namespace forestmap::server {
namespace {

v1::FrameResult& Skip(v1::FrameResult& result, const std::string& detail) {
  result.set_status(v1::FrameResult::SKIPPED);
  result.set_detail(detail);
  result.clear_map_from_sensor();
  return result;
}

ServiceError Stale(const std::string& name, int64_t current, int64_t base) {
  return ServiceError(grpc::StatusCode::ABORTED,
                      "map '" + name + "' is at version " + std::to_string(current) +
                          ", not at the base version " + std::to_string(base) +
                          " (rejected as stale; fetch the map and retry, or merge anyway)");
}

}  // namespace

bool ForestMapService::RelocalizeFrame(const std::string& map_name,
                                       const v1::ObservationFrame& frame,
                                       algorithms::FrameObservations& observations,
                                       std::string& detail) {
  if (frame.trees_size() < kMinQueryTrees) {
    detail = "no pose given and fewer than 3 trees to relocalize with";
    return false;
  }
  MapIndexCache::Entry entry;
  try {
    entry = index_cache_.Get(map_name);  // confirmed trees of the current version
  } catch (const PreconditionError& e) {
    detail = std::string("no pose given and the map cannot relocalize: ") + e.what();
    return false;
  }
  algorithms::RelocalizeQuery query;
  query.trees = observations.trees;
  if (frame.has_gravity()) query.gravity = FromProto(frame.gravity()).normalized();
  const algorithms::RelocalizeResult result =
      algorithms::Relocalize(*entry.index, query, options_.relocalizer);
  if (result.status != algorithms::RelocalizeStatus::kLocalized) {
    detail = std::string("relocalization: ") + algorithms::ToString(result.status) + ": " +
             result.detail;
    return false;
  }
  observations.map_from_sensor = result.map_from_sensor;
  return true;
}

void ForestMapService::RunObserve(grpc::CallbackServerContext* context,
                                  const v1::ObserveRequest& request,
                                  v1::ObserveResponse& response) {
  const auto start = std::chrono::steady_clock::now();
  Validate(request, options_.observe);
  ValidateRequestId(request.request_id());
  // A repeated request id: the first answer, before any relocalization or merge.
  if (!request.request_id().empty() &&
      ReplayRequest(store_, request.request_id(), "Observe", response)) {
    return;
  }
  const std::string& name = request.map_name();
  const bool reject_stale = request.conflict_policy() == v1::REJECT_IF_STALE;
  // Fail fast (unknown map, stale base) before relocalizing; the merge checks again.
  const storage::MapInfo before = store_.GetMap(name);
  if (reject_stale && before.version != request.base_version()) {
    throw Stale(name, before.version, request.base_version());
  }
  std::vector<algorithms::FrameObservations> frames;
  std::vector<v1::FrameResult*> merged_results;
  for (const v1::ObservationFrame& frame : request.frames()) {
    if (context->IsCancelled()) return;  // the client is gone; its status is CANCELLED anyway
    v1::FrameResult& result = *response.add_frames();
    result.set_frame_id(frame.frame_id());
    algorithms::FrameObservations observations = FromProto(frame, request.source());
    if (frame.trees().empty()) {
      Skip(result, "the frame has no trees");
      continue;
    }
    if (!frame.has_map_from_sensor()) {
      std::string detail;
      if (!RelocalizeFrame(name, frame, observations, detail)) {
        Skip(result, detail);
        continue;
      }
      result.set_relocalized(true);
    }
    result.set_status(v1::FrameResult::MERGED);
    *result.mutable_map_from_sensor() = ToProto(observations.map_from_sensor);
    frames.push_back(std::move(observations));
    merged_results.push_back(&result);
  }

  storage::MapInfo after = before;
  // False: a concurrent call with the same request id merged first; `response` is its answer.
  if (!frames.empty() &&
      !MergeObserved(context, request, frames, merged_results, response, after)) {
    return;
  }
  response.set_map_version(after.version);
  *response.mutable_map() = ToProto(after);
  const std::chrono::duration<double, std::milli> elapsed =
      std::chrono::steady_clock::now() - start;
  response.set_server_time_ms(elapsed.count());
}

bool ForestMapService::MergeObserved(grpc::CallbackServerContext* context,
                                     const v1::ObserveRequest& request,
                                     const std::vector<algorithms::FrameObservations>& frames,
                                     const std::vector<v1::FrameResult*>& merged,
                                     v1::ObserveResponse& response, storage::MapInfo& after) {
  storage::MergeNote note;
  note.kind = storage::VersionKind::kObserve;
  note.source = request.source();
  if (request.conflict_policy() == v1::REJECT_IF_STALE) {
    note.expected_version = request.base_version();
  }
  FramesMerge merge;
  const auto set_counts = [&] {
    for (size_t i = 0; i < merged.size(); ++i) {
      const FrameMergeCounts& counts = merge.counts[i];
      merged[i]->set_trees_associated(counts.associated);
      merged[i]->set_trees_added(counts.added);
      merged[i]->set_trees_promoted(counts.promoted);
      merged[i]->set_trees_ignored(counts.ignored);
    }
  };
  // The answer stored with the write: the frame results and the map it leaves.
  const auto encode = [&](const storage::MapInfo& info) {
    set_counts();
    v1::ObserveResponse answer = response;
    answer.set_map_version(info.version);
    *answer.mutable_map() = ToProto(info);
    return answer.SerializeAsString();
  };
  bool replayed = true;
  RunExactlyOnce(store_, context, request.request_id(), "Observe", response, encode, [&] {
    after = store_.Merge(request.map_name(), note, [&](storage::MergeReader& reader) {
      merge = MergeFrames(reader, frames, options_.merge, options_.consolidate);
      return merge.changes;
    });
    replayed = false;
  });
  if (replayed) return false;
  set_counts();
  return true;
}

void ForestMapService::RunRemoveSource(grpc::CallbackServerContext* context,
                                       const v1::RemoveSourceRequest& request,
                                       v1::RemoveSourceResponse& response) {
  Validate(request);
  storage::MergeNote note;
  note.kind = storage::VersionKind::kRemoveSource;
  note.source = request.source();
  SourceRemoval removal;
  const auto fill = [&](const storage::MapInfo& info, v1::RemoveSourceResponse& answer) {
    *answer.mutable_map() = ToProto(info);
    answer.set_observations_removed(
        static_cast<int64_t>(removal.changes.removed_observations.size()));
    answer.set_trees_updated(removal.trees_updated);
    answer.set_trees_removed(removal.trees_removed);
  };
  const auto encode = [&](const storage::MapInfo& info) {
    v1::RemoveSourceResponse answer;
    fill(info, answer);
    return answer.SerializeAsString();
  };
  RunExactlyOnce(store_, context, request.request_id(), "RemoveSource", response, encode, [&] {
    fill(store_.Merge(request.map_name(), note,
                      [&](storage::MergeReader& reader) {
                        removal = RemoveSourceChanges(reader, request.source(), options_.merge);
                        return removal.changes;
                      }),
         response);
  });
}

}  // namespace forestmap::server
