// ForestMapService: history retention on demand (PruneVersions). The --keep-versions policy after
// every write is the application layer's RetentionPolicy (server/app/retention.h), as is the prune.

#include "server/app/retention.h"
#include "server/grpc/convert.h"
#include "server/grpc/legacy_layout.h"
#include "server/grpc/replay.h"
#include "server/grpc/service.h"
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

void ForestMapService::RunPrune(grpc::CallbackServerContext* context, const Caller& caller,
                                const v1::PruneVersionsRequest& request,
                                v1::PruneVersionsResponse& response) {
  ValidateMapName(request.name(), "name");
  CheckKeep(request.keep());
  const std::string request_id = RequestId(request);  // field 50, or 3 of release 0.1.0
  // The stored answer of a request id holds the map; a repeat removes nothing, its counts are 0.
  const auto encode = Encoder<v1::PruneVersionsResponse>(
      [](const storage::MapInfo& info, auto& answer) { *answer.mutable_map() = ToProto(info); });
  // The id is bound to the request's content (name, keep), whichever field (50, or 3 of 0.1.0)
  // carried it.
  v1::PruneVersionsRequest content;
  content.set_name(request.name());
  content.set_keep(request.keep());
  const WriteCall call = WriteCallOf(context, caller, "PruneVersions", request.name(), request_id,
                                     ContentDigest(content));
  RunExactlyOnce(store_, call, response, encode,
                 [&] { Fill(PruneHistory(store_, request.name(), request.keep()), response); });
}

}  // namespace forestmap::server
