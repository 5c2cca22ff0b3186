#pragma once
// The ForestMap gRPC service (callback API): validate -> convert -> call the application layer
// (server/app: index cache, shared-map writes, exactly-once, retention) or storage / algorithms
// -> convert back -> finish. Every outcome is a grpc::Status built in server/grpc/status.cc; no
// exception crosses an RPC. Handlers never block gRPC's threads: everything that touches the
// store or the relocalizer runs on the service's thread pools (server/app/worker_pool.h): reads,
// map writes and map metadata each on their own, so no kind of call waits for another's threads.
//
// Every RPC first checks the caller's token (server/grpc/authorize.h): UNAUTHENTICATED,
// PERMISSION_DENIED.
// Statuses per RPC (besides INTERNAL for server faults and RESOURCE_EXHAUSTED from gRPC itself
// for a message over the server's receive limit); an INVALID_ARGUMENT of a check carries a
// google.rpc.BadRequest naming the field (server/grpc/status.h):
//   CreateMap    INVALID_ARGUMENT (name, description, crs), ALREADY_EXISTS
//   ListMaps     INVALID_ARGUMENT (page_size < 0, page_token; server/grpc/list_pages.h)
//   GetMap       INVALID_ARGUMENT (name), NOT_FOUND
//   DeleteMap    INVALID_ARGUMENT (name), NOT_FOUND
//   UploadTrees  INVALID_ARGUMENT (first message not a header naming the map, a later header or
//                other map name, a bad tree "trees[k]...", duplicate id within the
//                upload or, when appending, against the map), NOT_FOUND (map; checked on the
//                first message), RESOURCE_EXHAUSTED (more than max_upload_trees), CANCELLED
//                (client cancelled); ABORTED (write conflict); INVALID_ARGUMENT for a message
//                that cannot be decoded (e.g. a string that is not UTF-8). Nothing is written
//                unless OK.
//                With create_map: ALREADY_EXISTS, and the map exists only if the upload is OK.
//   ExportTrees  INVALID_ARGUMENT (name, box), NOT_FOUND, ABORTED (the map was deleted or the
//                version pruned during the export), CANCELLED (client stopped reading)
//   UploadTrees, ExportTrees: RESOURCE_EXHAUSTED when the client or the server has its limit of
//                open streams (ServiceOptions::streams)
//   UploadTrees, ExportTrees, Track: UNAUTHENTICATED / PERMISSION_DENIED as the stream opens,
//                before it takes a place; CANCELLED when it waits longer than
//                streams.idle_timeout for its client, or when its token is revoked
//                (server/grpc/stream_limits.h)
//   any RPC      RESOURCE_EXHAUSTED "server busy" when its pool's queue is full (max_queued_writes
//                for the map writes, max_queued_requests for the others);
//                INVALID_ARGUMENT for a request message that cannot be decoded
//                (server/grpc/decode_guard.h); RESOURCE_EXHAUSTED "database full",
//                FAILED_PRECONDITION "database read-only", DATA_LOSS, UNAVAILABLE for faults of the
//                database
//   Relocalize   INVALID_ARGUMENT (name, fewer than 3 trees, a bad tree / prior / gravity, a bad
//                map set), RESOURCE_EXHAUSTED (more than max_query_trees, or max_query_maps),
//                NOT_FOUND (map; a set's pattern finding no readable map), PERMISSION_DENIED (a
//                listed map the token may not read), FAILED_PRECONDITION (the map has no
//                confirmed trees). "Not localized" is not an error: it is OK with status
//                AMBIGUOUS or NOT_FOUND in the response. A set: server/grpc/map_set.h.
//   Observe      INVALID_ARGUMENT (name, source, no frames, duplicate frame ids, a bad tree
//                "frames[f].trees[i]..." / pose / gravity), RESOURCE_EXHAUSTED (observe limits),
//                NOT_FOUND (map), ABORTED (REJECT_IF_STALE and the map is past base_version).
//                A frame that cannot be relocalized is not an error: it is SKIPPED in the reply.
//   Track        per message, ending the stream: INVALID_ARGUMENT (first message not a header
//                naming the map, a later header or another map's name, a bad tree / gravity /
//                odometry), RESOURCE_EXHAUSTED (more
//                than max_query_trees), NOT_FOUND (map), FAILED_PRECONDITION (no confirmed
//                trees). A frame without a pose is not an error: it is answered LOST.
//   ListVersions INVALID_ARGUMENT (name, limit, page_size, page_token), NOT_FOUND (map)
//   RestoreVersion INVALID_ARGUMENT (name, version < 1), NOT_FOUND (map, or a version that
//                does not exist or predates the history)
//   RemoveSource INVALID_ARGUMENT (name, source), NOT_FOUND (map, or no observation of it)
//   PruneVersions INVALID_ARGUMENT (name, keep < 1), NOT_FOUND (map)
//   every write  INVALID_ARGUMENT (request_id malformed or used for another RPC),
//                DEADLINE_EXCEEDED (the deadline passed before the commit: nothing written)

#include <cstdint>

#include "algorithms/merging/map_merge.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/relocalization/tracking.h"
#include "forestmap/v1/forestmap_service.grpc.pb.h"
#include "server/app/map_index_cache.h"
#include "server/app/recent_answers.h"
#include "server/app/retention.h"
#include "server/app/worker_pool.h"
#include "server/grpc/stream_limits.h"
#include "server/grpc/validation.h"
#include "storage/map_store.h"

namespace forestmap::server {

class Authorizer;
struct Caller;

struct ServiceOptions {
  int max_query_trees = 20'000;  // trees per Relocalize request
  // Maps one Relocalize question over a set (RelocalizeRequest.maps) may search, after the prior
  // left out the far ones, and the searches they make (one per CRS, one per map without).
  int max_query_maps = kDefaultMaxQueryMaps;
  int max_query_searches = kDefaultMaxQuerySearches;
  int64_t max_upload_trees = 20'000'000;  // trees per UploadTrees stream (staged in the database)
  // Trees an upload stages per transaction: the most of an upload held in memory (count).
  int upload_stage_trees = 10'000;
  StreamLimitOptions streams;            // open upload / export streams, in all and per client
  int export_chunk_trees = 5'000;        // trees per ExportTrees message, at most
  int64_t export_chunk_bytes = 1 << 20;  // bytes per ExportTrees message, about (below the
                                         // clients' default 4 MiB receive limit)
  // Reads and writes are admitted apart, so that writes waiting for the database's write lock
  // never hold the threads reads need. Threads for reads that may take long or wait: Relocalize
  // and Track (index builds, waits for another call's build), ExportTrees pages. Waiting calls
  // hold a thread, so this is more than the core count; CPU use is bounded by the cores anyway.
  int worker_threads = 16;
  int max_queued_requests = 1'000;  // per read and admin pool; more -> RESOURCE_EXHAUSTED "busy"
  // Threads for the map writes: Observe, RestoreVersion, RemoveSource, PruneVersions, an upload's
  // staging and commit. SQLite serializes writes (one writer), PostgreSQL per map, so a few
  // threads keep the database busy; the others wait in the queue, holding no thread.
  int write_threads = 4;
  // Writes waiting for a write thread; more -> RESOURCE_EXHAUSTED "busy" (a queue this long
  // already waits seconds for SQLite's one writer).
  int max_queued_writes = 64;
  // The write threads run this much nicer than the others (0..19): when reads keep the CPU
  // full, writes get a small share of it (about a tenth at 10), and all of it when it is free.
  int write_nice = 10;
  int admin_threads = 4;             // threads for map metadata RPCs and upload map checks
  MapIndexCacheOptions index_cache;  // relocalization indexes kept in memory
  algorithms::RelocalizerOptions relocalizer;
  // Track sessions; their relocalizer options are `relocalizer` above.
  algorithms::TrackingOptions tracking;
  ObserveLimits observe;           // frames / trees per Observe request
  algorithms::MergeOptions merge;  // how Observe merges frames into a shared map
  bool consolidate = true;         // Observe's merge: SharedMapOptions::consolidate (server/app)
  // History retention (server/app/retention.h): after every write the map keeps its newest
  // keep_versions versions readable (0 = all; forestmapd --keep-versions). `map prune` does it on
  // demand.
  int64_t keep_versions = 0;
  // Token checks of every RPC (server/ops/auth.h); null: every call is allowed. Must outlive the
  // service.
  const Authorizer* authorizer = nullptr;
  void Check() const;  // throws std::invalid_argument
};

// UploadTrees is registered raw (ByteBuffer): the service decodes each message itself, so that an
// undecodable message is INVALID_ARGUMENT instead of looking like the end of the stream.
class ForestMapService final
    : public v1::ForestMap::WithRawCallbackMethod_UploadTrees<v1::ForestMap::CallbackService> {
 public:
  // `store` must outlive the service, and the service the grpc::Server it is registered with.
  // Throws std::invalid_argument for invalid options.
  ForestMapService(storage::MapStore& store, ServiceOptions options);

  const ServiceOptions& options() const { return options_; }
  const MapIndexCache& index_cache() const { return index_cache_; }
  const RecentAnswers& recent_answers() const { return recent_answers_; }  // the web page's
  const AnswerCounts& answer_counts() const { return answer_counts_; }     // the metrics'
  MapIndexCache& index_cache() { return index_cache_; }  // warmed by forestmapd's readiness
  const StreamLimits& stream_limits() const { return stream_limits_; }

  grpc::ServerUnaryReactor* CreateMap(grpc::CallbackServerContext* context,
                                      const v1::CreateMapRequest* request,
                                      v1::Map* response) override;
  grpc::ServerUnaryReactor* ListMaps(grpc::CallbackServerContext* context,
                                     const v1::ListMapsRequest* request,
                                     v1::ListMapsResponse* response) override;
  grpc::ServerUnaryReactor* GetMap(grpc::CallbackServerContext* context,
                                   const v1::GetMapRequest* request, v1::Map* response) override;
  grpc::ServerUnaryReactor* DeleteMap(grpc::CallbackServerContext* context,
                                      const v1::DeleteMapRequest* request,
                                      v1::DeleteMapResponse* response) override;
  // Messages are v1::UploadTreesRequest, the answer a v1::UploadTreesResponse (decoded and
  // encoded by the reactor, server/grpc/streams.h).
  grpc::ServerReadReactor<grpc::ByteBuffer>* UploadTrees(grpc::CallbackServerContext* context,
                                                         grpc::ByteBuffer* response) override;
  grpc::ServerWriteReactor<v1::ExportTreesResponse>* ExportTrees(
      grpc::CallbackServerContext* context, const v1::ExportTreesRequest* request) override;
  grpc::ServerUnaryReactor* Relocalize(grpc::CallbackServerContext* context,
                                       const v1::RelocalizeRequest* request,
                                       v1::RelocalizeResponse* response) override;
  grpc::ServerBidiReactor<v1::TrackRequest, v1::TrackResponse>* Track(
      grpc::CallbackServerContext* context) override;
  // Shared maps (observations.proto); bodies in server/grpc/observe_service.cc.
  grpc::ServerUnaryReactor* Observe(grpc::CallbackServerContext* context,
                                    const v1::ObserveRequest* request,
                                    v1::ObserveResponse* response) override;
  grpc::ServerUnaryReactor* ListVersions(grpc::CallbackServerContext* context,
                                         const v1::ListVersionsRequest* request,
                                         v1::ListVersionsResponse* response) override;
  grpc::ServerUnaryReactor* RestoreVersion(grpc::CallbackServerContext* context,
                                           const v1::RestoreVersionRequest* request,
                                           v1::RestoreVersionResponse* response) override;
  grpc::ServerUnaryReactor* RemoveSource(grpc::CallbackServerContext* context,
                                         const v1::RemoveSourceRequest* request,
                                         v1::RemoveSourceResponse* response) override;
  // History retention on demand; body in server/grpc/prune_service.cc.
  grpc::ServerUnaryReactor* PruneVersions(grpc::CallbackServerContext* context,
                                          const v1::PruneVersionsRequest* request,
                                          v1::PruneVersionsResponse* response) override;

 private:
  void RunObserve(grpc::CallbackServerContext* context, const Caller& caller,
                  const v1::ObserveRequest& request, v1::ObserveResponse& response);
  void RunRemoveSource(grpc::CallbackServerContext* context, const Caller& caller,
                       const v1::RemoveSourceRequest& request, v1::RemoveSourceResponse& response);
  void RunPrune(grpc::CallbackServerContext* context, const Caller& caller,
                const v1::PruneVersionsRequest& request, v1::PruneVersionsResponse& response);

  storage::MapStore& store_;
  ServiceOptions options_;
  MapIndexCache index_cache_;
  RecentAnswers recent_answers_;
  AnswerCounts answer_counts_;
  StreamLimits stream_limits_;
  IdleStreams idle_streams_;   // cancels upload, export and Track streams idle or revoked
  RetentionPolicy retention_;  // --keep-versions, after every write (unary and upload)
  // Declared last: destroyed (drained and joined) first, while what their jobs use is alive.
  WorkerPool admin_pool_;
  WorkerPool work_pool_;   // reads
  WorkerPool write_pool_;  // map writes (ServiceOptions::write_threads)
};

}  // namespace forestmap::server
