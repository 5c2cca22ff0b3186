#include "server/grpc/streams.h"

#include <chrono>
#include <stdexcept>
#include <utility>

#include "server/app/exactly_once.h"
#include "server/grpc/convert.h"
#include "server/grpc/geo_convert.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/ops/auth.h"

namespace forestmap::server {

// ---- Track ----

namespace {

algorithms::TrackingOptions SessionOptions(const ServiceOptions& options) {
  algorithms::TrackingOptions tracking = options.tracking;
  tracking.relocalizer = options.relocalizer;
  return tracking;
}

}  // namespace

TrackReactor::TrackReactor(MapIndexCache& index_cache, const ServiceOptions& options,
                           WorkerPool& work_pool, grpc::CallbackServerContext* context)
    : index_cache_(index_cache),
      work_pool_(work_pool),
      authorizer_(options.authorizer),
      context_(context),
      max_query_trees_(options.max_query_trees),
      tracker_(SessionOptions(options)) {
  StartRead(&request_);
}

void TrackReactor::OnReadDone(bool ok) {
  if (!ok) {  // the client closed its side (or is gone): the session ends
    Finish(grpc::Status::OK);
    return;
  }
  const bool queued = work_pool_.TrySubmit([this] {
    const grpc::Status status = RunGuarded("Track", [this] { Answer(); });
    if (status.ok()) {
      StartWrite(&response_);
    } else {
      Finish(grpc::Status(status.error_code(), "frame " + std::to_string(request_.frame_id()) +
                                                   ": " + status.error_message()));
    }
  });
  if (!queued) Finish(ServerBusy("Track"));
}

void TrackReactor::OnWriteDone(bool ok) {
  if (!ok) {
    Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the client stopped reading"));
    return;
  }
  StartRead(&request_);
}

void TrackReactor::Answer() {
  const auto start = std::chrono::steady_clock::now();
  if (map_name_.empty()) Authorize(authorizer_, *context_, "Track", request_.map_name());
  Validate(request_, map_name_, max_query_trees_);
  if (map_name_.empty()) map_name_ = request_.map_name();
  const MapIndexCache::Entry entry = index_cache_.Get(map_name_);
  response_ = ToProto(tracker_.Step(*entry.index, FromProto(request_)));
  response_.set_frame_id(request_.frame_id());
  v1::RelocalizeResponse& result = *response_.mutable_result();
  result.set_map_version(entry.version);
  if (request_.has_client_stamp_ns()) result.set_client_stamp_ns(request_.client_stamp_ns());
  if (entry.to_wgs84) AddGeodetic(result, *entry.to_wgs84);
  const std::chrono::duration<double, std::milli> elapsed =
      std::chrono::steady_clock::now() - start;
  result.set_server_time_ms(elapsed.count());
}

}  // namespace forestmap::server
