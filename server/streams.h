#pragma once
// The streaming RPCs of ForestMapService as callback reactors. Each deletes itself in OnDone.

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <functional>
#include <vector>

#include "algorithms/relocalization/tracking.h"
#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/tracking.pb.h"
#include "server/map_index_cache.h"
#include "server/validation.h"
#include "server/worker_pool.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct ServiceOptions;
class Authorizer;

// UploadTrees: reads every message, validates it as it arrives (the first must name an existing
// map: NOT_FOUND comes before the client sends the rest), accumulates the trees, and writes
// them in ONE MapStore::WriteTrees call when the client closes the stream. A cancelled or failed
// upload writes nothing. Store calls run on the pools: the map check on `admin_pool`, the write
// on `work_pool`; validation and conversion of each message run on gRPC's thread.
// Messages arrive raw and are decoded here: one that cannot be decoded as a
// v1::UploadTreesRequest (a string that is not UTF-8, corrupt bytes) fails the upload with
// INVALID_ARGUMENT naming the message; gRPC's typed reader would report it as the end of the
// stream and the trees before it would be committed. `response` gets the encoded
// v1::UploadTreesResponse.
class UploadTreesReactor final : public grpc::ServerReadReactor<grpc::ByteBuffer> {
 public:
  UploadTreesReactor(storage::MapStore& store, const ServiceOptions& options,
                     WorkerPool& admin_pool, WorkerPool& work_pool,
                     grpc::CallbackServerContext* context, grpc::ByteBuffer* response);

  void OnReadDone(bool ok) override;
  void OnDone() override { delete this; }

 private:
  void Accept();  // the message in buffer_; throws
  void Commit();  // throws
  // Runs `body` on `pool`, then reads the next message, or finishes on error.
  void ThenReadNext(WorkerPool& pool, std::function<void()> body);

  storage::MapStore& store_;
  const Authorizer* authorizer_;  // checked on the first message
  WorkerPool& admin_pool_;
  WorkerPool& work_pool_;
  grpc::CallbackServerContext* context_;
  grpc::ByteBuffer* response_;
  grpc::ByteBuffer buffer_;  // the message being read
  v1::UploadTreesRequest request_;
  UploadValidator validator_;
  std::string request_id_;  // from the first message (exactly-once, server/exactly_once.h)
  int64_t keep_versions_;   // ServiceOptions::keep_versions
  std::vector<storage::TreeRecord> trees_;
};

// ExportTrees: streams the trees of one consistent read in chunks (export_chunk_trees trees or
// about export_chunk_bytes bytes, whichever comes first), every message carrying the same
// map_version. An empty result is one message with no trees, so the client still learns the
// version. With a box, trees come from MapStore::TreesInBox, bracketed by two GetMap calls that
// must agree on the version (retried a few times, then ABORTED). The read runs on `work_pool`.
class ExportTreesReactor final : public grpc::ServerWriteReactor<v1::ExportTreesResponse> {
 public:
  // `request` must stay valid until the reactor finishes (gRPC guarantees it).
  ExportTreesReactor(storage::MapStore& store, const ServiceOptions& options, WorkerPool& work_pool,
                     grpc::CallbackServerContext* context, const v1::ExportTreesRequest* request);

  void OnWriteDone(bool ok) override;
  void OnDone() override { delete this; }

 private:
  void Load(storage::MapStore& store, const v1::ExportTreesRequest& request);  // throws
  void WriteNext();

  int64_t chunk_trees_;
  int64_t chunk_bytes_;
  int64_t version_ = 0;
  std::vector<storage::TreeRecord> trees_;
  size_t next_ = 0;
  bool wrote_any_ = false;
  v1::ExportTreesResponse response_;
};

// Track: one frame at a time, in order: read a frame, answer it on `work_pool` (the session's
// Tracker, algorithms/relocalization/tracking.h), write the answer, read the next. The index comes
// from the cache for every frame, so a session moves on to a new map version as soon as there is
// one. A bad frame, an unknown map or a map without trees ends the stream with its status, the
// message prefixed with the frame ("frame 12: trees[3].position.x is NaN").
class TrackReactor final : public grpc::ServerBidiReactor<v1::TrackRequest, v1::TrackResponse> {
 public:
  TrackReactor(MapIndexCache& index_cache, const ServiceOptions& options, WorkerPool& work_pool,
               grpc::CallbackServerContext* context);

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnDone() override { delete this; }

 private:
  void Answer();  // request_ -> response_; throws

  MapIndexCache& index_cache_;
  WorkerPool& work_pool_;
  const Authorizer* authorizer_;  // checked on the first frame
  grpc::CallbackServerContext* context_;
  int max_query_trees_;
  algorithms::Tracker tracker_;
  std::string map_name_;  // from the first frame
  v1::TrackRequest request_;
  v1::TrackResponse response_;
};

}  // namespace forestmap::server
