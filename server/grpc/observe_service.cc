// ForestMapService: the bodies of the shared-map RPCs (Observe, RemoveSource): validate, convert,
// the application layer's step (server/app/shared_map.h), convert back.

#include <chrono>
#include <string>

#include "server/app/shared_map.h"
#include "server/grpc/convert.h"
#include "server/grpc/replay.h"
#include "server/grpc/service.h"
#include "server/grpc/validation.h"

namespace forestmap::server {
namespace {

SharedMapOptions SharedMapOptionsOf(const ServiceOptions& options) {
  SharedMapOptions shared;
  shared.relocalizer = options.relocalizer;
  shared.merge = options.merge;
  shared.consolidate = options.consolidate;
  return shared;
}

}  // namespace

void ForestMapService::RunObserve(grpc::CallbackServerContext* context,
                                  const v1::ObserveRequest& request,
                                  v1::ObserveResponse& response) {
  const auto start = std::chrono::steady_clock::now();
  Validate(request, options_.observe);
  ObserveCall call = FromProto(request);
  call.write = WriteCallOf(context, request.request_id(), "Observe");
  const auto encode = [](const ObserveOutcome& outcome) {
    return ToProto(outcome).SerializeAsString();
  };
  const Written<ObserveOutcome> written =
      ApplyObserve(store_, index_cache_, call, SharedMapOptionsOf(options_), encode,
                   [context] { return context->IsCancelled(); });
  if (written.replayed) {
    ParseStoredAnswer(request.request_id(), *written.replayed, response);
    return;
  }
  // A cancelled call: the client is gone, its status is CANCELLED anyway.
  if (written.outcome.cancelled) return;
  response = ToProto(written.outcome);
  const std::chrono::duration<double, std::milli> elapsed =
      std::chrono::steady_clock::now() - start;
  response.set_server_time_ms(elapsed.count());
}

void ForestMapService::RunRemoveSource(grpc::CallbackServerContext* context,
                                       const v1::RemoveSourceRequest& request,
                                       v1::RemoveSourceResponse& response) {
  Validate(request);
  const auto fill = [](const SourceRemovalOutcome& outcome) {
    v1::RemoveSourceResponse answer;
    *answer.mutable_map() = ToProto(outcome.map);
    answer.set_observations_removed(outcome.observations_removed);
    answer.set_trees_updated(outcome.trees_updated);
    answer.set_trees_removed(outcome.trees_removed);
    return answer;
  };
  const Written<SourceRemovalOutcome> written = ApplyRemoveSource(
      store_, WriteCallOf(context, request.request_id(), "RemoveSource"), request.name(),
      request.source(), options_.merge,
      [&fill](const SourceRemovalOutcome& outcome) { return fill(outcome).SerializeAsString(); });
  if (written.replayed) {
    ParseStoredAnswer(request.request_id(), *written.replayed, response);
  } else {
    response = fill(written.outcome);
  }
}

}  // namespace forestmap::server
