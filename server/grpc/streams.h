#pragma once
// The streaming RPCs of ForestMapService as callback reactors. Each deletes itself in OnDone.

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/relocalization/tracking.h"
#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/tracking.pb.h"
#include "server/app/map_index_cache.h"
#include "server/app/recent_answers.h"
#include "server/app/retention.h"
#include "server/app/tree_pages.h"
#include "server/app/worker_pool.h"
#include "server/grpc/stream_limits.h"
#include "server/grpc/upload_validator.h"
#include "server/grpc/validation.h"
#include "server/ops/auth.h"
#include "storage/map_store.h"
#include "storage/staged_writes.h"

namespace forestmap::server {

struct ServiceOptions;
class Authorizer;

// What the upload and export reactors use; all must outlive them (the service owns them).
struct StreamDeps {
  storage::MapStore& store;
  const ServiceOptions& options;
  WorkerPool& admin_pool;  // the first message's checks (map exists, replayed request id)
  WorkerPool& work_pool;   // reads: export pages
  WorkerPool& write_pool;  // writes: an upload's staging and commit
  StreamLimits& limits;    // a stream over its limit is RESOURCE_EXHAUSTED before anything else
  IdleStreams& idle;       // streams waiting too long for their client are cancelled
  const RetentionPolicy& retention;  // after a committed upload
};

// Every stream is authorized as it opens, for the role its RPC needs (server/grpc/stream_limits.h),
// before it takes a place among the open streams, and is cancelled when it waits longer than
// StreamLimitOptions::idle_timeout for its client.
//
// UploadTrees (server/grpc/upload_stream.cc): reads the messages one at a time, validates each as
// it arrives (the first must name the map: NOT_FOUND, or ALREADY_EXISTS with create_map, before the
// client sends the rest), and stages the trees in the database through MapStore::BeginUpload in
// chunks of options.upload_stage_trees, so that an upload holds at most one chunk in memory.
// When the client closes the stream, the last chunk is staged and the upload committed (with
// create_map, together with the new map). A cancelled or failed upload commits nothing and its
// staged rows are removed. Messages arrive raw and are decoded here: one that cannot be decoded
// as a v1::UploadTreesRequest (a string that is not UTF-8, corrupt bytes) fails the upload with
// INVALID_ARGUMENT naming the message; gRPC's typed reader would report it as the end of the
// stream. A request id stored before: the rest of the stream is read and checked without staging,
// then answered from the store if it is the same request (map, caller, content), INVALID_ARGUMENT
// otherwise. `response` gets the encoded v1::UploadTreesResponse.
class UploadTreesReactor final : public grpc::ServerReadReactor<grpc::ByteBuffer> {
 public:
  UploadTreesReactor(const StreamDeps& deps, grpc::CallbackServerContext* context,
                     grpc::ByteBuffer* response);

  void OnReadDone(bool ok) override;
  void OnDone() override;  // an upload not committed is aborted (on a pool), then `delete this`

 private:
  // Frees the stream's place, aborts an upload not committed, then Finish.
  void End(const grpc::Status& status);
  void Open();        // on the admin pool: authorizes, takes a place, reads the first message
  void Read();        // the next message (the stream then waits for its client)
  void Accept();      // the message in buffer_ -> chunk_; throws
  void Begin();       // first message: authorizes the map, begins the upload (or a replay); throws
  void StageChunk();  // chunk_ -> the database; throws
  void Commit();      // throws
  // Runs `body` on `pool`, then reads the next message, or finishes on error.
  void ThenReadNext(WorkerPool& pool, std::function<void()> body);
  void EncodeResponse(const v1::UploadTreesResponse& answer);

  StreamDeps deps_;
  const Authorizer* authorizer_;  // checked as the stream opens and on the first message
  grpc::CallbackServerContext* context_;
  grpc::ByteBuffer* response_;
  std::unique_ptr<IdleStreams::Watch> watch_;
  std::unique_ptr<StreamLimits::Slot> slot_;
  grpc::ByteBuffer buffer_;  // the message being read
  v1::UploadTreesRequest request_;
  UploadValidator validator_;
  std::string request_id_;  // from the first message (exactly-once, server/app/exactly_once.h)
  std::string digest_;      // of the messages so far: what request_id_ is bound to, with caller_
  Caller caller_;           // from Begin
  bool replaying_ = false;  // request_id_ was stored: read the rest, answer from the store
  storage::UploadPlan plan_;
  std::unique_ptr<storage::TreeUpload> upload_;  // null before Begin and after Commit
  std::vector<storage::TreeRecord> chunk_;       // received, not yet staged
};

// ExportTrees (server/grpc/export_stream.cc): streams the trees of one map version, reading them
// page by page (server/app/tree_pages.h, one short read per page of export_chunk_trees trees) and
// reading the next page only when the client has taken the last message (gRPC flow control),
// so an export holds one page in memory however big the map and however slow the client.
// Messages carry export_chunk_trees trees or about export_chunk_bytes bytes, whichever comes
// first, every one the same map_version. An empty result is one message with no trees, so the
// client still learns the version.
class ExportTreesReactor final : public grpc::ServerWriteReactor<v1::ExportTreesResponse> {
 public:
  // `request` must stay valid until the reactor finishes (gRPC guarantees it).
  ExportTreesReactor(const StreamDeps& deps, grpc::CallbackServerContext* context,
                     const v1::ExportTreesRequest* request);

  void OnWriteDone(bool ok) override;
  void OnDone() override { delete this; }

 private:
  void End(const grpc::Status& status);  // frees the stream's place, then Finish
  void Start();                          // authorizes, picks the version; throws
  void LoadPage();                       // the next page into page_; throws
  void ReadThenWrite(bool start);        // on the work pool: (Start,) LoadPage, then WriteNext
  void WriteNext();

  StreamDeps deps_;
  grpc::CallbackServerContext* context_;
  const v1::ExportTreesRequest* request_;
  std::unique_ptr<IdleStreams::Watch> watch_;
  std::unique_ptr<StreamLimits::Slot> slot_;
  std::optional<TreePages> pages_;  // from Start
  int64_t version_ = 0;
  storage::Boundary boundary_;                  // of version_, sent with the first message
  std::vector<std::string> attribute_columns_;  // of version_, sent with the first message
  std::vector<storage::TreeRecord> page_;
  size_t next_ = 0;  // next tree of page_ to send
  bool wrote_any_ = false;
  v1::ExportTreesResponse response_;
};

// Track: the header (which names the map), then one frame at a time, in order: read a frame,
// answer it on `work_pool` (the session's Tracker, algorithms/relocalization/tracking.h), write
// the answer, read the next. The index comes from the cache for every frame, so a session moves
// on to a new map version as soon as there is one. A bad message, an unknown map or a map without
// trees ends the stream with its status, the message prefixed with the frame when it is one
// ("frame 12: frame.trees[3].position.x is NaN").
//
// A header naming a set of maps (TrackHeader.maps, resolved as for Relocalize: the maps with trees
// the caller may read, at most max_query_maps) tracks across them: the session tracks in the map
// it last found the sensor in; when that map loses the pose (or before the first fix), the frame
// is relocalized over the set (server/app/map_set_relocalize.h) near the prediction (within the
// tracking prior radius, grown per frame lost; over the whole set once global_after frames are
// lost), and the session goes on in the map found, with a fresh tracker there. Each answer's
// result.map_name names the map the session tracks in (empty before the first fix).
class TrackReactor final : public grpc::ServerBidiReactor<v1::TrackRequest, v1::TrackResponse> {
 public:
  // Each frame's answer is counted in `counts` (which must outlive the stream).
  // `store` and `options` must outlive the stream (the service's).
  TrackReactor(storage::MapStore& store, MapIndexCache& index_cache, const ServiceOptions& options,
               WorkerPool& work_pool, IdleStreams& idle, AnswerCounts& counts,
               grpc::CallbackServerContext* context);

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnDone() override { delete this; }

 private:
  bool Answer();  // request_ -> response_ (true), or a header read (false); throws
  // A frame of a session over a set of maps; `entry`: the index of the map it was answered in.
  algorithms::TrackingStep StepOverSet(const algorithms::TrackingFrame& frame,
                                       std::optional<MapIndexCache::Entry>& entry);
  void Read();  // the next message (the stream then waits for its client)
  void End(const grpc::Status& status);

  storage::MapStore& store_;
  const ServiceOptions& options_;
  MapIndexCache& index_cache_;
  WorkerPool& work_pool_;
  const Authorizer* authorizer_;  // checked as the stream opens and on the first message
  AnswerCounts& counts_;
  grpc::CallbackServerContext* context_;
  std::unique_ptr<IdleStreams::Watch> watch_;
  int max_query_trees_;
  algorithms::Tracker tracker_;
  std::string map_name_;          // from the first message; over a set, the map of the last fix
  Caller caller_;                 // as the stream opened
  bool over_set_ = false;         // the header named a set of maps ...
  std::vector<std::string> set_;  // ... these, with trees, readable by the caller
  int set_frames_lost_ = 0;       // frames in a row without a fix before the first one
  v1::TrackRequest request_;
  v1::TrackResponse response_;
};

}  // namespace forestmap::server
