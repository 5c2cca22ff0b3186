#include "server/grpc/service.h"

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "algorithms/core/check.h"
#include "server/app/map_crs.h"
#include "server/app/worker_pool.h"
#include "server/grpc/authorize.h"
#include "server/grpc/convert.h"
#include "server/grpc/geo_convert.h"
#include "server/grpc/list_pages.h"
#include "server/grpc/map_set.h"
#include "server/grpc/replay.h"
#include "server/grpc/status.h"
#include "server/grpc/streams.h"
#include "server/grpc/validation.h"
#include "server/ops/logging.h"

namespace forestmap::server {
namespace {

using algorithms::Require;

// Runs a unary RPC body on `pool` and finishes the call with its status. The body outlives the
// handler, so it must capture by value (request, response and context stay valid until Finish).
template <typename Body>
grpc::ServerUnaryReactor* AnswerOn(WorkerPool& pool, grpc::CallbackServerContext* context,
                                   const char* rpc, Body body) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  const bool queued = pool.TrySubmit(
      [reactor, rpc, body = std::move(body)]() mutable { reactor->Finish(RunGuarded(rpc, body)); });
  if (!queued) reactor->Finish(ServerBusy(rpc));
  return reactor;
}

ServiceOptions Checked(ServiceOptions options) {
  options.Check();
  return options;
}

// What the application layer cannot answer to a caller (a retention failure after a committed
// write, a pool job that threw) goes to the log.
void LogFault(std::string_view message) { Log(LogLevel::kWarn, message); }

}  // namespace

void ServiceOptions::Check() const {
  Require(max_query_trees >= kMinQueryTrees, "ServiceOptions.max_query_trees must be >= 3");
  Require(max_query_maps >= 1 && max_query_searches >= 1,
          "ServiceOptions.max_query_maps and max_query_searches must be >= 1");
  Require(max_upload_trees >= 1, "ServiceOptions.max_upload_trees must be >= 1");
  Require(export_chunk_trees >= 1, "ServiceOptions.export_chunk_trees must be >= 1");
  Require(export_chunk_bytes >= 1, "ServiceOptions.export_chunk_bytes must be >= 1");
  Require(worker_threads >= 1, "ServiceOptions.worker_threads must be >= 1");
  Require(admin_threads >= 1, "ServiceOptions.admin_threads must be >= 1");
  Require(max_queued_requests >= 1, "ServiceOptions.max_queued_requests must be >= 1");
  Require(write_threads >= 1, "ServiceOptions.write_threads must be >= 1");
  Require(max_queued_writes >= 1, "ServiceOptions.max_queued_writes must be >= 1");
  Require(write_nice >= 0 && write_nice <= 19, "ServiceOptions.write_nice must be in [0, 19]");
  index_cache.Check();
  relocalizer.Check();
  Require(observe.max_frames >= 1, "ServiceOptions.observe.max_frames must be >= 1");
  Require(observe.max_frame_trees >= 1, "ServiceOptions.observe.max_frame_trees must be >= 1");
  Require(observe.max_request_trees >= 1, "ServiceOptions.observe.max_request_trees must be >= 1");
  merge.Check();
  tracking.Check();
  Require(keep_versions >= 0, "ServiceOptions.keep_versions must be >= 0 (0 keeps all)");
  Require(upload_stage_trees >= 1, "ServiceOptions.upload_stage_trees must be >= 1");
  streams.Check();
}

ForestMapService::ForestMapService(storage::MapStore& store, ServiceOptions options)
    : store_(store),
      options_(Checked(std::move(options))),
      index_cache_(store, options_.index_cache),
      stream_limits_(options_.streams),
      idle_streams_(options_.streams, options_.authorizer),
      retention_(store, options_.keep_versions, LogFault),
      admin_pool_(options_.admin_threads, options_.max_queued_requests, LogFault),
      work_pool_(options_.worker_threads, options_.max_queued_requests, LogFault),
      write_pool_(options_.write_threads, options_.max_queued_writes, LogFault,
                  options_.write_nice) {}

grpc::ServerUnaryReactor* ForestMapService::CreateMap(grpc::CallbackServerContext* context,
                                                      const v1::CreateMapRequest* request,
                                                      v1::Map* response) {
  return AnswerOn(admin_pool_, context, "CreateMap", [this, context, request, response] {
    const Caller caller = Authorize(options_.authorizer, *context, "CreateMap", request->name());
    Validate(*request);
    const auto encode =
        Encoder<v1::Map>([](const storage::MapInfo& info, v1::Map& map) { map = ToProto(info); });
    const WriteCall call = WriteCallOf(context, caller, "CreateMap", request->name(),
                                       request->request_id(), ContentDigest(*request));
    RunExactlyOnce(store_, call, *response, encode, [&] {
      *response = ToProto(
          store_.CreateMap(request->name(), request->description(), CanonicalCrs(request->crs())));
    });
  });
}

grpc::ServerUnaryReactor* ForestMapService::ListMaps(grpc::CallbackServerContext* context,
                                                     const v1::ListMapsRequest* request,
                                                     v1::ListMapsResponse* response) {
  return AnswerOn(admin_pool_, context, "ListMaps", [this, context, request, response] {
    const Caller caller = Authorize(options_.authorizer, *context, "ListMaps", "");
    *response = ListMapsPage(store_, caller, *request);
  });
}

grpc::ServerUnaryReactor* ForestMapService::GetMap(grpc::CallbackServerContext* context,
                                                   const v1::GetMapRequest* request,
                                                   v1::Map* response) {
  return AnswerOn(admin_pool_, context, "GetMap", [this, context, request, response] {
    Authorize(options_.authorizer, *context, "GetMap", request->name());
    Validate(*request);
    *response = ToProto(store_.GetMap(request->name()));
  });
}

grpc::ServerUnaryReactor* ForestMapService::DeleteMap(grpc::CallbackServerContext* context,
                                                      const v1::DeleteMapRequest* request,
                                                      v1::DeleteMapResponse* response) {
  return AnswerOn(admin_pool_, context, "DeleteMap", [this, context, request, response] {
    const Caller caller = Authorize(options_.authorizer, *context, "DeleteMap", request->name());
    Validate(*request);
    const auto encode = [](const storage::MapInfo&) { return std::string(); };
    const WriteCall call = WriteCallOf(context, caller, "DeleteMap", request->name(),
                                       request->request_id(), ContentDigest(*request));
    RunExactlyOnce(store_, call, *response, encode, [&] { store_.DeleteMap(request->name()); });
    index_cache_.Evict(request->name());
  });
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ForestMapService::UploadTrees(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return new UploadTreesReactor({store_, options_, admin_pool_, work_pool_, write_pool_,
                                 stream_limits_, idle_streams_, retention_},
                                context, response);
}

grpc::ServerWriteReactor<v1::ExportTreesResponse>* ForestMapService::ExportTrees(
    grpc::CallbackServerContext* context, const v1::ExportTreesRequest* request) {
  return new ExportTreesReactor({store_, options_, admin_pool_, work_pool_, write_pool_,
                                 stream_limits_, idle_streams_, retention_},
                                context, request);
}

grpc::ServerUnaryReactor* ForestMapService::Relocalize(grpc::CallbackServerContext* context,
                                                       const v1::RelocalizeRequest* request,
                                                       v1::RelocalizeResponse* response) {
  const auto start = std::chrono::steady_clock::now();
  return AnswerOn(work_pool_, context, "Relocalize", [this, context, request, response, start] {
    const Caller caller = Authorize(options_.authorizer, *context, "Relocalize", request->name());
    Validate(*request, options_.max_query_trees, options_.max_query_maps);
    if (context->IsCancelled()) return;  // the client is gone; its status is CANCELLED anyway
    const algorithms::RelocalizeQuery query = FromProto(*request);
    const std::vector<storage::MapInfo> maps =
        request->has_maps() ? ResolveMapSet(store_, caller, "Relocalize", request->maps(), query,
                                            options_.relocalizer, options_.max_query_maps,
                                            options_.max_query_searches)
                            : std::vector<storage::MapInfo>{MapNamed(request->name())};
    // No lock around the relocalizer: concurrent queries share the immutable indexes.
    const MapSetAnswer answer = RelocalizeInMaps(index_cache_, maps, query, options_.relocalizer);
    *response = ToProto(answer);
    if (request->has_client_stamp_ns()) response->set_client_stamp_ns(request->client_stamp_ns());
    std::optional<geo::GeodeticPose> geodetic;
    if (answer.reported) {
      const MapAnswer& reported = answer.answers[*answer.reported];
      if (reported.entry.to_wgs84) geodetic = AddGeodetic(*response, *reported.entry.to_wgs84);
    }
    const std::chrono::duration<double, std::milli> elapsed =
        std::chrono::steady_clock::now() - start;
    response->set_server_time_ms(elapsed.count());
    recent_answers_.Add(response->map_name(), answer.result, geodetic);
    answer_counts_.Relocalized(answer.result);
  });
}

grpc::ServerBidiReactor<v1::TrackRequest, v1::TrackResponse>* ForestMapService::Track(
    grpc::CallbackServerContext* context) {
  return new TrackReactor(store_, index_cache_, options_, work_pool_, idle_streams_, answer_counts_,
                          context);
}

grpc::ServerUnaryReactor* ForestMapService::Observe(grpc::CallbackServerContext* context,
                                                    const v1::ObserveRequest* request,
                                                    v1::ObserveResponse* response) {
  return AnswerOn(write_pool_, context, "Observe", [this, context, request, response] {
    const Caller caller = Authorize(options_.authorizer, *context, "Observe", request->name());
    RunObserve(context, caller, *request, *response);
    retention_.AfterWrite(request->name());
  });
}

grpc::ServerUnaryReactor* ForestMapService::ListVersions(grpc::CallbackServerContext* context,
                                                         const v1::ListVersionsRequest* request,
                                                         v1::ListVersionsResponse* response) {
  return AnswerOn(admin_pool_, context, "ListVersions", [this, context, request, response] {
    Authorize(options_.authorizer, *context, "ListVersions", request->name());
    *response = ListVersionsPage(store_, *request);
  });
}

grpc::ServerUnaryReactor* ForestMapService::RestoreVersion(grpc::CallbackServerContext* context,
                                                           const v1::RestoreVersionRequest* request,
                                                           v1::RestoreVersionResponse* response) {
  return AnswerOn(write_pool_, context, "RestoreVersion", [this, context, request, response] {
    const Caller caller =
        Authorize(options_.authorizer, *context, "RestoreVersion", request->name());
    Validate(*request);
    const auto encode = Encoder<v1::RestoreVersionResponse>(
        [](const storage::MapInfo& info, auto& answer) { *answer.mutable_map() = ToProto(info); });
    const WriteCall call = WriteCallOf(context, caller, "RestoreVersion", request->name(),
                                       request->request_id(), ContentDigest(*request));
    RunExactlyOnce(store_, call, *response, encode, [&] {
      *response->mutable_map() =
          ToProto(store_.RestoreVersion(request->name(), request->version()));
    });
    retention_.AfterWrite(request->name());
  });
}

grpc::ServerUnaryReactor* ForestMapService::RemoveSource(grpc::CallbackServerContext* context,
                                                         const v1::RemoveSourceRequest* request,
                                                         v1::RemoveSourceResponse* response) {
  return AnswerOn(write_pool_, context, "RemoveSource", [this, context, request, response] {
    const Caller caller = Authorize(options_.authorizer, *context, "RemoveSource", request->name());
    RunRemoveSource(context, caller, *request, *response);
    retention_.AfterWrite(request->name());
  });
}

grpc::ServerUnaryReactor* ForestMapService::PruneVersions(grpc::CallbackServerContext* context,
                                                          const v1::PruneVersionsRequest* request,
                                                          v1::PruneVersionsResponse* response) {
  return AnswerOn(write_pool_, context, "PruneVersions", [this, context, request, response] {
    const Caller caller =
        Authorize(options_.authorizer, *context, "PruneVersions", request->name());
    RunPrune(context, caller, *request, *response);
  });
}

}  // namespace forestmap::server
