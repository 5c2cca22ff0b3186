// ForestMapService: history retention (PruneVersions, --keep-versions).

#include <string>

#include "server/app/exactly_once.h"
#include "server/grpc/convert.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/grpc/validation.h"

namespace forestmap::server {
namespace {

void Fill(const storage::PruneResult& result, v1::PruneVersionsResponse& response) {
  *response.mutable_map() = ToProto(result.info);
  response.set_versions_removed(result.versions_removed);
  response.set_tree_rows_removed(result.tree_rows_removed);
  response.set_observation_rows_removed(result.observation_rows_removed);
}

}  // namespace

void ForestMapService::RunPrune(grpc::CallbackServerContext* context,
                                const v1::PruneVersionsRequest& request,
                                v1::PruneVersionsResponse& response) {
  ValidateMapName(request.map_name(), "map_name");
  if (request.keep() < 1) {
    throw ValidationError("keep is " + std::to_string(request.keep()) +
                          "; at least the current version must stay (keep >= 1)");
  }
  // The stored answer of a request id holds the map; a repeat removes nothing, its counts are 0.
  const auto encode = Encoder<v1::PruneVersionsResponse>(
      [](const storage::MapInfo& info, auto& answer) { *answer.mutable_map() = ToProto(info); });
  RunExactlyOnce(store_, context, request.request_id(), "PruneVersions", response, encode,
                 [&] { Fill(store_.PruneVersions(request.map_name(), request.keep()), response); });
}

void ForestMapService::ApplyRetention(const std::string& map) noexcept {
  if (options_.keep_versions <= 0) return;
  try {
    store_.PruneVersions(map, options_.keep_versions);
  } catch (const std::exception& e) {
    LogLine("retention of map \"" + map + "\" failed (the write stands): " + e.what());
  } catch (...) {
  }
}

}  // namespace forestmap::server
