#include "client/lib/forestmap_client.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <utility>

#include "client/lib/proto_convert.h"
#include "proto/error_details.h"

namespace forestmap::client {
namespace {

std::chrono::system_clock::time_point After(double seconds) {
  return std::chrono::system_clock::now() +
         std::chrono::duration_cast<std::chrono::system_clock::duration>(
             std::chrono::duration<double>(seconds));
}

// When the first connection attempt failed, calls get this long at most: a refused connection
// fails at once, and an address that swallows packets should not hang the command.
constexpr double kUnconnectedCallTimeout = 1.0;  // s

// A fresh request id: 128 random bits in hex (exactly-once writes, one id per logical write).
std::string NewRequestId() {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  char id[40];
  std::snprintf(id, sizeof(id), "fm-%016llx%016llx", static_cast<unsigned long long>(rng()),
                static_cast<unsigned long long>(rng()));
  return id;
}

// " (field: trees[3].position.x)": the fields the server named in its error details
// (google.rpc.BadRequest), shown after its message.
std::string ViolatedFields(const grpc::Status& status) {
  const std::vector<FieldViolation> violations = BadRequestViolations(status);
  if (violations.empty()) return "";
  std::string fields;
  for (const FieldViolation& violation : violations) {
    fields += (fields.empty() ? "" : ", ") + violation.field;
  }
  return (violations.size() == 1 ? " (field: " : " (fields: ") + fields + ")";
}

bool Retriable(const grpc::Status& status) {
  return status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED ||
         status.error_code() == grpc::StatusCode::UNAVAILABLE;
}

}  // namespace

void ClientOptions::Check() const {
  if (!(connect_timeout > 0)) throw std::invalid_argument("connect_timeout must be > 0 s");
  if (!(call_timeout > 0)) throw std::invalid_argument("call_timeout must be > 0 s");
  if (!(stream_timeout > 0)) throw std::invalid_argument("stream_timeout must be > 0 s");
  if (upload_chunk_trees < 1) throw std::invalid_argument("upload_chunk_trees must be >= 1");
  if (max_receive_bytes < 1) throw std::invalid_argument("max_receive_bytes must be >= 1");
  if (write_attempts < 1) throw std::invalid_argument("write_attempts must be >= 1");
  if (tls_cert.empty() != tls_key.empty()) {
    throw std::invalid_argument("a client certificate needs both --tls-cert and --tls-key");
  }
  if (token.find_first_of("\r\n") != std::string::npos) {
    throw std::invalid_argument("the token must be one line");
  }
}

ForestMapClient::ForestMapClient(std::string address, const ClientOptions& options)
    : address_(std::move(address)), options_(options) {
  options_.Check();
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(options_.max_receive_bytes);
  if (options_.own_connection) arguments.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  std::stringstream list(address_);
  for (std::string one; std::getline(list, one, ',');) {
    if (one.empty()) continue;
    addresses_.push_back(one);
    channels_.push_back(grpc::CreateCustomChannel(one, ChannelCredentialsFor(options_), arguments));
    stubs_.push_back(v1::ForestMap::NewStub(channels_.back()));
  }
  if (addresses_.empty()) {
    throw std::invalid_argument("no server address in '" + address_ + "' (want host:port[,...])");
  }
  channel_ = channels_[0];
  stub_ = stubs_[0].get();
}

template <typename Call>
auto ForestMapClient::WithFailover(const Call& call) -> decltype(call()) {
  for (size_t attempt = 1;; ++attempt) {
    try {
      return call();
    } catch (const RpcError& e) {
      const bool unreachable = e.code() == grpc::StatusCode::UNAVAILABLE ||
                               (e.code() == grpc::StatusCode::DEADLINE_EXCEEDED && !connected_);
      if (!unreachable || attempt >= addresses_.size()) throw;
    }
    current_ = (current_ + 1) % addresses_.size();
    channel_ = channels_[current_];
    stub_ = stubs_[current_].get();
    connect_checked_ = connected_ = false;
    ++retries_;
  }
}

void ForestMapClient::EnsureConnected() {
  if (connect_checked_) return;
  connect_checked_ = true;
  // Like WaitForConnected, but gives up at the first failed attempt: a refused connection is
  // reported at once instead of after the whole timeout of retries.
  const auto deadline = After(options_.connect_timeout);
  grpc_connectivity_state state = channel_->GetState(/*try_to_connect=*/true);
  while (state != GRPC_CHANNEL_READY && state != GRPC_CHANNEL_TRANSIENT_FAILURE &&
         state != GRPC_CHANNEL_SHUTDOWN) {
    if (!channel_->WaitForStateChange(state, deadline)) break;  // timed out
    state = channel_->GetState(/*try_to_connect=*/true);
  }
  connected_ = state == GRPC_CHANNEL_READY;
}

std::unique_ptr<grpc::ClientContext> ForestMapClient::NewContext(double timeout) {
  EnsureConnected();
  auto context = std::make_unique<grpc::ClientContext>();
  if (!options_.token.empty()) context->AddMetadata("authorization", "Bearer " + options_.token);
  if (!connected_) {
    context->set_deadline(
        After(timeout > 0 ? std::min(timeout, kUnconnectedCallTimeout) : kUnconnectedCallTimeout));
  } else if (timeout > 0) {
    context->set_deadline(After(timeout));
  }
  return context;
}

void ForestMapClient::Check(const grpc::Status& status, const char* call) const {
  if (status.ok()) return;
  const grpc::StatusCode code = status.error_code();
  // UNAVAILABLE "database unavailable: ..." comes from a server that was reached (its database
  // was locked or unreachable): reported as the server's answer, not as an unreachable server.
  const bool database_fault = status.error_message().starts_with("database unavailable");
  if ((code == grpc::StatusCode::UNAVAILABLE && !database_fault) ||
      (code == grpc::StatusCode::DEADLINE_EXCEEDED && !connected_)) {
    std::ostringstream detail;
    if (code == grpc::StatusCode::DEADLINE_EXCEEDED) {
      detail << "no connection within " << options_.connect_timeout << " s";
    } else {
      detail << status.error_message();
    }
    throw RpcError(code, "cannot reach forestmapd at " + addresses_[current_] + ": " +
                             detail.str() + " (is it running? use --server)");
  }
  throw RpcError(code, std::string(call) + ": " + StatusCodeName(code) + ": " +
                           status.error_message() + ViolatedFields(status));
}

template <typename Response, typename Method, typename Request>
Response ForestMapClient::Unary(Method method, const Request& request, const char* call) {
  Response response;
  const auto context = NewContext(options_.call_timeout);
  Check((stub_->*method)(context.get(), request, &response), call);
  connected_ = true;
  return response;
}

void ForestMapClient::WriteWithRetries(
    const std::function<grpc::Status(const std::string&)>& attempt, const char* call) {
  const std::string request_id = NewRequestId();
  grpc::Status status;
  for (int i = 0; i < options_.write_attempts; ++i) {
    status = attempt(request_id);
    if (status.ok() || !Retriable(status) || !connected_) break;
  }
  Check(status, call);
  connected_ = true;
}

template <typename Response, typename Method, typename Request>
Response ForestMapClient::UnaryWrite(Method method, Request request, const char* call) {
  Response response;
  WriteWithRetries(
      [&](const std::string& request_id) {
        request.set_request_id(request_id);
        const auto context = NewContext(options_.call_timeout);
        return (stub_->*method)(context.get(), request, &response);
      },
      call);
  return response;
}

v1::Map ForestMapClient::CreateMap(const std::string& name, const std::string& description,
                                   const std::string& crs) {
  v1::CreateMapRequest request;
  request.set_name(name);
  request.set_description(description);
  request.set_crs(crs);
  return UnaryWrite<v1::Map>(&v1::ForestMap::Stub::CreateMap, request, "CreateMap");
}

std::vector<v1::Map> ForestMapClient::ListMaps() {
  std::vector<v1::Map> maps;
  v1::ListMapsRequest request;
  do {  // page by page (the server's page size), each page from any replica
    const auto page = WithFailover([&] {
      return Unary<v1::ListMapsResponse>(&v1::ForestMap::Stub::ListMaps, request, "ListMaps");
    });
    maps.insert(maps.end(), page.maps().begin(), page.maps().end());
    request.set_page_token(page.next_page_token());
  } while (!request.page_token().empty());
  return maps;
}

v1::Map ForestMapClient::GetMap(const std::string& name) {
  v1::GetMapRequest request;
  request.set_name(name);
  return WithFailover(
      [&] { return Unary<v1::Map>(&v1::ForestMap::Stub::GetMap, request, "GetMap"); });
}

void ForestMapClient::DeleteMap(const std::string& name) {
  v1::DeleteMapRequest request;
  request.set_name(name);
  UnaryWrite<v1::DeleteMapResponse>(&v1::ForestMap::Stub::DeleteMap, request, "DeleteMap");
}

v1::UploadTreesResponse ForestMapClient::UploadTrees(const std::string& name,
                                                     const std::vector<MapTreeRow>& rows,
                                                     bool replace, const UploadProgress& progress,
                                                     const std::optional<Boundary>& boundary,
                                                     const std::vector<std::string>& columns) {
  v1::UploadTreesHeader header;
  header.set_name(name);
  header.set_replace(replace);
  if (boundary) *header.mutable_boundary() = ToProto(*boundary);
  header.mutable_attribute_columns()->Add(columns.begin(), columns.end());
  return Upload(header, rows, progress);
}

v1::UploadTreesResponse ForestMapClient::CreateMapWithTrees(
    const std::string& name, const std::string& description, const std::string& crs,
    const std::vector<MapTreeRow>& rows, const UploadProgress& progress,
    const std::optional<Boundary>& boundary, const std::vector<std::string>& columns) {
  v1::UploadTreesHeader header;
  header.set_name(name);
  header.set_create_map(true);
  header.set_description(description);
  header.set_crs(crs);
  if (boundary) *header.mutable_boundary() = ToProto(*boundary);
  header.mutable_attribute_columns()->Add(columns.begin(), columns.end());
  return Upload(header, rows, progress);
}

v1::UploadTreesResponse ForestMapClient::Upload(v1::UploadTreesHeader header,
                                                const std::vector<MapTreeRow>& rows,
                                                const UploadProgress& progress) {
  v1::UploadTreesResponse response;
  WriteWithRetries(
      [&](const std::string& request_id) {
        header.set_request_id(request_id);
        return UploadOnce(header, rows, progress, response);
      },
      "UploadTrees");
  return response;
}

grpc::Status ForestMapClient::UploadOnce(const v1::UploadTreesHeader& header,
                                         const std::vector<MapTreeRow>& rows,
                                         const UploadProgress& progress,
                                         v1::UploadTreesResponse& response) {
  const auto context = NewContext(options_.stream_timeout);
  const auto writer = stub_->UploadTrees(context.get(), &response);
  const size_t chunk = static_cast<size_t>(options_.upload_chunk_trees);
  v1::UploadTreesRequest request;
  *request.mutable_header() = header;
  // A failed write means the server ended the call; Finish() says why.
  bool open = writer->Write(request);
  for (size_t sent = 0; open && sent < rows.size();) {
    const size_t end = std::min(rows.size(), sent + chunk);
    google::protobuf::RepeatedPtrField<v1::Tree>& trees = *request.mutable_chunk()->mutable_trees();
    trees.Clear();
    trees.Reserve(static_cast<int>(end - sent));
    for (size_t i = sent; i < end; ++i) *trees.Add() = ToProto(rows[i]);
    open = writer->Write(request);
    sent = end;
    if (open && progress) progress(static_cast<int64_t>(sent), static_cast<int64_t>(rows.size()));
  }
  writer->WritesDone();
  return writer->Finish();
}

ExportedTrees ForestMapClient::ExportTrees(const std::string& name, const std::optional<Box2>& box,
                                           int64_t version, const ExportProgress& progress) {
  v1::ExportTreesRequest request;
  request.set_name(name);
  request.set_version(version);
  if (box) {
    request.mutable_box()->set_min_x(box->min_x);
    request.mutable_box()->set_min_y(box->min_y);
    request.mutable_box()->set_max_x(box->max_x);
    request.mutable_box()->set_max_y(box->max_y);
  }
  return WithFailover([&] { return ExportTreesOnce(request, progress); });
}

ExportedTrees ForestMapClient::ExportTreesOnce(const v1::ExportTreesRequest& request,
                                               const ExportProgress& progress) {
  const auto context = NewContext(options_.stream_timeout);
  const auto reader = stub_->ExportTrees(context.get(), request);
  ExportedTrees exported;
  v1::ExportTreesResponse chunk;
  bool first = true;
  while (reader->Read(&chunk)) {
    if (first) {
      exported.map_version = chunk.map_version();
      exported.boundary = FromProto(chunk.boundary());
      exported.attribute_columns.assign(chunk.attribute_columns().begin(),
                                        chunk.attribute_columns().end());
    }
    if (!first && chunk.map_version() != exported.map_version) {
      context->TryCancel();
      reader->Finish();
      throw RpcError(grpc::StatusCode::INTERNAL, "ExportTrees: the server mixed map versions " +
                                                     std::to_string(exported.map_version) +
                                                     " and " + std::to_string(chunk.map_version()));
    }
    first = false;
    for (const v1::Tree& tree : chunk.trees()) {
      exported.trees.push_back(FromProto(tree));
      exported.states.push_back(StateOf(tree));
    }
    if (progress) progress(std::ssize(exported.trees));
  }
  Check(reader->Finish(), "ExportTrees");
  connected_ = true;
  return exported;
}

std::optional<v1::MapSet> MapSetOf(const MapSelection& maps) {
  if (maps.names.empty() && maps.name_pattern.empty() && !maps.all_readable) return std::nullopt;
  v1::MapSet set;
  for (const std::string& map : maps.names) set.add_names(map);
  set.set_name_pattern(maps.name_pattern);
  set.set_all_readable(maps.all_readable);
  return set;
}

v1::RelocalizeResponse ForestMapClient::Relocalize(
    const std::string& name, const std::vector<algorithms::DetectedTree>& trees,
    const std::optional<PriorPosition>& prior, const std::optional<Eigen::Vector3d>& gravity) {
  MapSelection one;
  one.name = name;
  return Relocalize(one, trees, prior, gravity);
}

v1::RelocalizeResponse ForestMapClient::Relocalize(
    const MapSelection& maps, const std::vector<algorithms::DetectedTree>& trees,
    const std::optional<PriorPosition>& prior, const std::optional<Eigen::Vector3d>& gravity) {
  v1::RelocalizeRequest request;
  request.set_name(maps.name);
  if (std::optional<v1::MapSet> set = MapSetOf(maps)) *request.mutable_maps() = std::move(*set);
  request.mutable_trees()->Reserve(static_cast<int>(trees.size()));
  for (const algorithms::DetectedTree& tree : trees) *request.add_trees() = ToProto(tree);
  if (prior) {
    request.mutable_prior()->set_x(prior->x);
    request.mutable_prior()->set_y(prior->y);
    request.mutable_prior()->set_radius_m(prior->radius_m);
  }
  if (gravity) {
    request.mutable_gravity()->set_x(gravity->x());
    request.mutable_gravity()->set_y(gravity->y());
    request.mutable_gravity()->set_z(gravity->z());
  }
  return WithFailover([&] {
    return Unary<v1::RelocalizeResponse>(&v1::ForestMap::Stub::Relocalize, request, "Relocalize");
  });
}

v1::ObserveResponse ForestMapClient::Observe(const std::string& name,
                                             const std::vector<ObservedFrame>& frames,
                                             const ObserveOptions& options) {
  v1::ObserveRequest request;
  request.set_name(name);
  request.set_source(options.source);
  request.set_base_version(options.base_version);
  request.set_conflict_policy(options.reject_stale ? v1::CONFLICT_POLICY_REJECT_IF_STALE
                                                   : v1::CONFLICT_POLICY_MERGE);
  request.mutable_frames()->Reserve(static_cast<int>(frames.size()));
  for (const ObservedFrame& frame : frames) {
    v1::ObservationFrame* out = request.add_frames();
    out->set_frame_id(frame.frame_id);
    out->mutable_trees()->Reserve(static_cast<int>(frame.trees.size()));
    for (const algorithms::DetectedTree& tree : frame.trees) *out->add_trees() = ToProto(tree);
    if (frame.map_from_sensor) *out->mutable_map_from_sensor() = ToProto(*frame.map_from_sensor);
    out->set_position_sigma(frame.position_sigma);
    out->set_yaw_sigma(frame.yaw_sigma);
  }
  request.set_sensor_range(options.sensor_range);
  request.set_detection_probability(options.detection_probability);
  request.set_merge_only(options.merge_only);
  return UnaryWrite<v1::ObserveResponse>(&v1::ForestMap::Stub::Observe, request, "Observe");
}

std::vector<v1::MapVersion> ForestMapClient::ListVersions(const std::string& name, int limit) {
  std::vector<v1::MapVersion> versions;
  v1::ListVersionsRequest request;
  request.set_name(name);
  request.set_limit(limit);
  do {  // page by page (the server's page size), each page from any replica
    const auto page = WithFailover([&] {
      return Unary<v1::ListVersionsResponse>(&v1::ForestMap::Stub::ListVersions, request,
                                             "ListVersions");
    });
    versions.insert(versions.end(), page.versions().begin(), page.versions().end());
    request.set_page_token(page.next_page_token());
  } while (!request.page_token().empty());
  return versions;
}

v1::Map ForestMapClient::RestoreVersion(const std::string& name, int64_t version) {
  v1::RestoreVersionRequest request;
  request.set_name(name);
  request.set_version(version);
  return UnaryWrite<v1::RestoreVersionResponse>(&v1::ForestMap::Stub::RestoreVersion, request,
                                                "RestoreVersion")
      .map();
}

v1::RemoveSourceResponse ForestMapClient::RemoveSource(const std::string& name,
                                                       const std::string& source) {
  v1::RemoveSourceRequest request;
  request.set_name(name);
  request.set_source(source);
  return UnaryWrite<v1::RemoveSourceResponse>(&v1::ForestMap::Stub::RemoveSource, request,
                                              "RemoveSource");
}

v1::PruneVersionsResponse ForestMapClient::PruneVersions(const std::string& name, int64_t keep) {
  v1::PruneVersionsRequest request;
  request.set_name(name);
  request.set_keep(keep);
  return UnaryWrite<v1::PruneVersionsResponse>(&v1::ForestMap::Stub::PruneVersions, request,
                                               "PruneVersions");
}

}  // namespace forestmap::client
