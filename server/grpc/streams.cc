#include "server/grpc/streams.h"

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "server/grpc/authorize.h"
#include "server/grpc/convert.h"
#include "server/grpc/geo_convert.h"
#include "server/grpc/legacy_layout.h"
#include "server/grpc/map_set.h"
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

TrackReactor::TrackReactor(storage::MapStore& store, MapIndexCache& index_cache,
                           const ServiceOptions& options, WorkerPool& work_pool, IdleStreams& idle,
                           AnswerCounts& counts, grpc::CallbackServerContext* context)
    : store_(store),
      options_(options),
      index_cache_(index_cache),
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
        RunGuarded("Track", [this] { caller_ = Authorize(authorizer_, *context_, "Track", ""); });
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
  const bool first = map_name_.empty() && !over_set_;
  if (first) {
    // The first message: authorized for the map it names before anything else is looked at.
    Authorize(authorizer_, *context_, "Track", FirstMessageMap(request_));
  }
  TrackMessage message = ReadTrackMessage(request_, over_set_ ? kSetSession : map_name_,
                                          max_query_trees_, options_.max_query_maps);
  if (first && message.maps) {
    over_set_ = true;
    for (const storage::MapInfo& info :
         ResolveMapSet(store_, caller_, "Track", *message.maps, {}, options_.relocalizer,
                       options_.max_query_maps, options_.max_query_searches)) {
      set_.push_back(info.name);
    }
  } else if (first) {
    map_name_ = message.map;
  }
  if (!message.frame) return false;  // a header: nothing to answer
  const v1::TrackFrame& frame = *message.frame;
  std::optional<MapIndexCache::Entry> entry;
  algorithms::TrackingStep step;
  if (over_set_) {
    step = StepOverSet(FromProto(frame), entry);
  } else {
    entry = index_cache_.Get(map_name_);
    step = tracker_.Step(*entry->index, FromProto(frame));
  }
  counts_.Tracked(step.state);
  response_ = ToProto(step);
  response_.set_frame_id(frame.frame_id());
  v1::RelocalizeResponse& result = *response_.mutable_result();
  if (entry) {
    result.set_map_name(map_name_);
    result.set_map_version(entry->version);
  }
  if (frame.has_client_stamp_ns()) result.set_client_stamp_ns(frame.client_stamp_ns());
  if (entry && entry->to_wgs84) AddGeodetic(result, *entry->to_wgs84);
  const std::chrono::duration<double, std::milli> elapsed =
      std::chrono::steady_clock::now() - start;
  result.set_server_time_ms(elapsed.count());
  return true;
}

algorithms::TrackingStep TrackReactor::StepOverSet(const algorithms::TrackingFrame& frame,
                                                   std::optional<MapIndexCache::Entry>& entry) {
  algorithms::TrackingStep step;
  if (!map_name_.empty()) {
    entry = index_cache_.Get(map_name_);
    step = tracker_.Step(*entry->index, frame);
    if (step.state != algorithms::TrackState::kLost) return step;
  }
  // The map of the last fix lost the pose (or there is none yet): the frame over the whole set,
  // near the prediction while there is one and the track was lost only lately.
  const int lost = map_name_.empty() ? set_frames_lost_ + 1 : step.frames_lost;
  const algorithms::TrackingOptions& tracking = options_.tracking;
  algorithms::RelocalizeQuery query = frame.query;
  query.prior.reset();
  if (tracker_.prediction() && lost <= tracking.global_after) {
    query.prior = algorithms::PriorPose{
        *tracker_.prediction(), tracking.prior_radius + tracking.radius_growth * (lost - 1)};
  }
  std::vector<storage::MapInfo> maps;
  for (const std::string& name : set_) {
    try {
      maps.push_back(store_.GetMap(name));
    } catch (const storage::StorageError& error) {  // deleted since the session began: skipped
      if (error.code() != storage::StorageError::Code::kNotFound) throw;
    }
  }
  const MapSetAnswer found = RelocalizeInMaps(
      index_cache_, CandidateMaps(maps, query, options_.relocalizer), query, options_.relocalizer);
  if (found.result.status == algorithms::RelocalizeStatus::kLocalized) {
    // A fresh session in the map found: the frame searched there again, which seeds the tracker.
    map_name_ = found.answers[*found.reported].map;
    entry = index_cache_.Get(map_name_);  // the map's own index (a union's ids are not its own)
    tracker_ = algorithms::Tracker(SessionOptions(options_));
    set_frames_lost_ = 0;
    return tracker_.Step(*entry->index, frame);
  }
  if (!map_name_.empty()) return step;  // lost in its map, and found in none
  set_frames_lost_ = lost;
  step.state = algorithms::TrackState::kLost;
  step.method = query.prior ? algorithms::TrackMethod::kPrior : algorithms::TrackMethod::kGlobal;
  step.result = found.result;
  step.frames_lost = lost;
  return step;
}

}  // namespace forestmap::server
