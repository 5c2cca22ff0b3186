#include "server/streams.h"

#include <chrono>
#include <stdexcept>
#include <utility>

#include "server/auth.h"
#include "server/convert.h"
#include "server/exactly_once.h"
#include "server/geo_convert.h"
#include "server/service.h"
#include "server/status.h"

namespace forestmap::server {

// ---- UploadTrees ----

UploadTreesReactor::UploadTreesReactor(storage::MapStore& store, const ServiceOptions& options,
                                       WorkerPool& admin_pool, WorkerPool& work_pool,
                                       grpc::CallbackServerContext* context,
                                       grpc::ByteBuffer* response)
    : store_(store),
      authorizer_(options.authorizer),
      admin_pool_(admin_pool),
      work_pool_(work_pool),
      context_(context),
      response_(response),
      validator_(options.max_upload_trees),
      keep_versions_(options.keep_versions) {
  StartRead(&buffer_);
}

void UploadTreesReactor::OnReadDone(bool ok) {
  if (!ok) {
    // The stream ended: either the client closed it (commit) or the call is gone.
    if (context_->IsCancelled()) {
      const grpc::Status cancelled(grpc::StatusCode::CANCELLED,
                                   "upload cancelled; nothing was written");
      LogStatus("UploadTrees", cancelled);
      Finish(cancelled);
      return;
    }
    const bool queued =
        work_pool_.TrySubmit([this] { Finish(RunGuarded("UploadTrees", [this] { Commit(); })); });
    if (!queued) Finish(ServerBusy("UploadTrees"));
    return;
  }
  const bool first = validator_.messages() == 0;
  const grpc::Status status = RunGuarded("UploadTrees", [this, first] {
    Accept();  // decodes and checks the message; the first one names the map
    if (first) Authorize(authorizer_, *context_, "UploadTrees", validator_.map_name());
  });
  if (!status.ok()) {
    Finish(status);  // the rest of the stream is dropped; nothing was written
    return;
  }
  if (first) {
    // Fail early for an unknown map, before the client streams millions of trees.
    ThenReadNext(admin_pool_, [this] { store_.GetMap(validator_.map_name()); });
    return;
  }
  StartRead(&buffer_);
}

void UploadTreesReactor::ThenReadNext(WorkerPool& pool, std::function<void()> body) {
  const bool queued = pool.TrySubmit([this, body = std::move(body)] {
    const grpc::Status status = RunGuarded("UploadTrees", body);
    if (status.ok()) {
      StartRead(&buffer_);
    } else {
      Finish(status);
    }
  });
  if (!queued) Finish(ServerBusy("UploadTrees"));
}

void UploadTreesReactor::Accept() {
  const grpc::Status decoded =
      grpc::SerializationTraits<v1::UploadTreesRequest>::Deserialize(&buffer_, &request_);
  buffer_.Clear();
  if (!decoded.ok()) {
    throw ValidationError("upload message " + std::to_string(validator_.messages()) + " (after " +
                          std::to_string(validator_.trees()) +
                          " trees) cannot be decoded as an UploadTreesRequest (a string that is "
                          "not UTF-8, or corrupt bytes); nothing was written");
  }
  if (validator_.messages() == 0) {
    request_id_ = request_.request_id();
    ValidateRequestId(request_id_);
  } else if (!request_.request_id().empty() && request_.request_id() != request_id_) {
    throw ValidationError("request_id (upload message " + std::to_string(validator_.messages()) +
                          ") differs from the first message's; only the first sets it");
  }
  validator_.Accept(request_);
  // No reserve() per message: exact reservations would make the accumulation quadratic.
  for (const v1::Tree& tree : request_.trees()) trees_.push_back(FromProto(tree));
  request_.Clear();
}

void UploadTreesReactor::Commit() {
  // The client may have given up while the commit waited in the work queue. (A cancel during
  // the write itself cannot be honoured: the transaction then commits whole.)
  if (context_->IsCancelled()) {
    throw ServiceError(grpc::StatusCode::CANCELLED, "upload cancelled; nothing was written");
  }
  validator_.Finish();
  const storage::WriteMode mode =
      validator_.replace() ? storage::WriteMode::kReplace : storage::WriteMode::kAppend;
  const int64_t received = validator_.trees();
  const auto fill = [received](const storage::MapInfo& info, v1::UploadTreesResponse& answer) {
    *answer.mutable_map() = ToProto(info);
    answer.set_trees_received(received);
  };
  v1::UploadTreesResponse response;
  RunExactlyOnce(store_, context_, request_id_, "UploadTrees", response,
                 Encoder<v1::UploadTreesResponse>(fill),
                 [&] { fill(store_.WriteTrees(validator_.map_name(), trees_, mode), response); });
  trees_ = {};
  if (keep_versions_ > 0) {  // history retention (forestmapd --keep-versions)
    try {
      store_.PruneVersions(validator_.map_name(), keep_versions_);
    } catch (const std::exception& e) {
      LogLine("UploadTrees: retention failed (the upload stands): " + std::string(e.what()));
    }
  }
  bool own_buffer = false;
  const grpc::Status encoded = grpc::SerializationTraits<v1::UploadTreesResponse>::Serialize(
      response, response_, &own_buffer);
  if (!encoded.ok()) throw std::runtime_error("cannot encode the UploadTrees answer");
}

// ---- ExportTrees ----

ExportTreesReactor::ExportTreesReactor(storage::MapStore& store, const ServiceOptions& options,
                                       WorkerPool& work_pool, grpc::CallbackServerContext* context,
                                       const v1::ExportTreesRequest* request)
    : chunk_trees_(options.export_chunk_trees), chunk_bytes_(options.export_chunk_bytes) {
  const Authorizer* authorizer = options.authorizer;
  const bool queued = work_pool.TrySubmit([this, &store, authorizer, context, request] {
    const grpc::Status status = RunGuarded("ExportTrees", [&] {
      Authorize(authorizer, *context, "ExportTrees", request->map_name());
      Load(store, *request);
    });
    if (status.ok()) {
      WriteNext();
    } else {
      Finish(status);
    }
  });
  if (!queued) Finish(ServerBusy("ExportTrees"));
}

void ExportTreesReactor::Load(storage::MapStore& store, const v1::ExportTreesRequest& request) {
  Validate(request);
  const std::string& name = request.map_name();
  if (request.version() != 0) {
    // An older version: read it whole (one consistent snapshot), then cut the box.
    storage::MapSnapshot snapshot = store.ReadMapVersion(name, request.version());
    version_ = snapshot.info.version;
    trees_ = std::move(snapshot.trees);
    if (request.has_box()) {
      const storage::Extent box = FromProto(request.box());
      std::erase_if(trees_, [&](const storage::TreeRecord& tree) {
        return tree.x < box.min_x || tree.x > box.max_x || tree.y < box.min_y || tree.y > box.max_y;
      });
    }
    return;
  }
  if (!request.has_box()) {
    storage::MapSnapshot snapshot = store.ReadMap(name);
    version_ = snapshot.info.version;
    trees_ = std::move(snapshot.trees);
    return;
  }
  // TreesInBox uses the spatial index but carries no version: accept its answer only when the
  // map's version (and creation time) did not change around it.
  constexpr int kAttempts = 3;
  const storage::Extent box = FromProto(request.box());
  for (int attempt = 0; attempt < kAttempts; ++attempt) {
    const storage::MapInfo before = store.GetMap(name);
    std::vector<storage::TreeRecord> trees = store.TreesInBox(name, box);
    const storage::MapInfo after = store.GetMap(name);
    if (before.version == after.version && before.created_unix_ms == after.created_unix_ms) {
      version_ = after.version;
      trees_ = std::move(trees);
      return;
    }
  }
  throw ServiceError(grpc::StatusCode::ABORTED, "map \"" + name + "\" changed during " +
                                                    std::to_string(kAttempts) +
                                                    " attempts to export it; retry");
}

void ExportTreesReactor::WriteNext() {
  if (wrote_any_ && next_ >= trees_.size()) {
    trees_ = {};
    Finish(grpc::Status::OK);
    return;
  }
  response_.Clear();
  response_.set_map_version(version_);
  int64_t bytes = 0;
  while (next_ < trees_.size() && response_.trees_size() < chunk_trees_ && bytes < chunk_bytes_) {
    v1::Tree* tree = response_.add_trees();
    *tree = ToProto(trees_[next_++]);
    bytes += static_cast<int64_t>(tree->ByteSizeLong());
  }
  wrote_any_ = true;
  StartWrite(&response_);
}

void ExportTreesReactor::OnWriteDone(bool ok) {
  if (!ok) {
    const grpc::Status cancelled(grpc::StatusCode::CANCELLED, "the client stopped reading");
    LogStatus("ExportTrees", cancelled);
    Finish(cancelled);
    return;
  }
  WriteNext();
}

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
