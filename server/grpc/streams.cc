#include "server/grpc/streams.h"

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "server/grpc/authorize.h"
#include "server/grpc/convert.h"
#include "server/grpc/geo_convert.h"
#include "server/grpc/legacy_layout.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"

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
                           WorkerPool& work_pool, IdleStreams& idle, AnswerCounts& counts,
                           grpc::CallbackServerContext* context)
    : index_cache_(index_cache),
      work_pool_(work_pool),
      authorizer_(options.authorizer),
      counts_(counts),
      context_(context),
      watch_(idle.Add(*context, "Track")),
      max_query_trees_(options.max_query_trees),
      tracker_(SessionOptions(options)) {
  // Authorized as it opens, for Track's role on some map (the map: on the first message). The
  // check reads the token store: on the pool, not on gRPC's thread.
  const bool queued = work_pool_.TrySubmit([this] {
    const grpc::Status opened =
        RunGuarded("Track", [this] { Authorize(authorizer_, *context_, "Track", ""); });
    if (opened.ok()) {
      Read();
    } else {
      End(opened);
    }
  });
  if (!queued) End(ServerBusy("Track"));
}

void TrackReactor::Read() {
  watch_->Waiting();
  StartRead(&request_);
}

void TrackReactor::End(const grpc::Status& status) {
  watch_->Working();
  Finish(status);
}

void TrackReactor::OnReadDone(bool ok) {
  watch_->Working();
  if (!ok) {  // the client closed its side (or is gone): the session ends
    Finish(grpc::Status::OK);
    return;
  }
  const bool queued = work_pool_.TrySubmit([this] {
    const std::optional<int64_t> frame_id = FrameIdOf(request_);
    bool answered = false;
    const grpc::Status status = RunGuarded("Track", [this, &answered] { answered = Answer(); });
    if (!status.ok()) {
      const std::string prefix = frame_id ? "frame " + std::to_string(*frame_id) + ": " : "";
      Finish(grpc::Status(status.error_code(), prefix + status.error_message(),
                          status.error_details()));
    } else if (answered) {
      watch_->Waiting();  // until the client takes the answer
      StartWrite(&response_);
    } else {
      Read();
    }
  });
  if (!queued) Finish(ServerBusy("Track"));
}

void TrackReactor::OnWriteDone(bool ok) {
  watch_->Working();
  if (!ok) {
    Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the client stopped reading"));
    return;
  }
  Read();
}

bool TrackReactor::Answer() {
  const auto start = std::chrono::steady_clock::now();
  if (map_name_.empty()) {
    // The first message: authorized for the map it names before anything else is looked at.
    Authorize(authorizer_, *context_, "Track", FirstMessageMap(request_));
  }
  TrackMessage message = ReadTrackMessage(request_, map_name_, max_query_trees_);
  if (map_name_.empty()) map_name_ = message.map;
  if (!message.frame) return false;  // a header: nothing to answer
  const v1::TrackFrame& frame = *message.frame;
  const MapIndexCache::Entry entry = index_cache_.Get(map_name_);
  const algorithms::TrackingStep step = tracker_.Step(*entry.index, FromProto(frame));
  counts_.Tracked(step.state);
  response_ = ToProto(step);
  response_.set_frame_id(frame.frame_id());
  v1::RelocalizeResponse& result = *response_.mutable_result();
  result.set_map_version(entry.version);
  if (frame.has_client_stamp_ns()) result.set_client_stamp_ns(frame.client_stamp_ns());
  if (entry.to_wgs84) AddGeodetic(result, *entry.to_wgs84);
  const std::chrono::duration<double, std::milli> elapsed =
      std::chrono::steady_clock::now() - start;
  result.set_server_time_ms(elapsed.count());
  return true;
}

}  // namespace forestmap::server
