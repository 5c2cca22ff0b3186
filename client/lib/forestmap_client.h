#pragma once
// A blocking client of the ForestMap service (see proto/forestmap/v1/forestmap_service.proto),
// the core of the embeddable client library (CMake: find_package(ForestMap CONFIG), target
// ForestMap::client; pkg-config: forestmap-client). Units and frames are the API's: metres,
// radians unless a name says deg, poses a_from_b.

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/polygon.h"
#include "client/io/tree_csv.h"
#include "client/lib/proto_convert.h"
#include "forestmap/v1/forestmap_service.grpc.pb.h"
#include "proto/status_code_name.h"

namespace forestmap::client {

// A failed call. The message is ready for a user: for an unreachable server it reads
// "cannot reach forestmapd at ADDR: <detail> (is it running? use --server)"; otherwise it is the
// server's message prefixed with the call and the status name, e.g.
// "GetMap: NOT_FOUND: no map named 'x'", followed by the fields the server named in its error
// details (google.rpc.BadRequest) when it did: "... is NaN; ... (field: trees[3].position.x)".
class RpcError : public std::runtime_error {
 public:
  RpcError(grpc::StatusCode code, const std::string& message)
      : std::runtime_error(message), code_(code) {}
  grpc::StatusCode code() const { return code_; }

 private:
  grpc::StatusCode code_;
};

struct ClientOptions {
  double connect_timeout = 3.0;      // s, wait for a connection before the first call
  double call_timeout = 30.0;        // s, deadline of each unary call
  double stream_timeout = 600.0;     // s, deadline of a whole upload or export
  int upload_chunk_trees = 5000;     // trees per UploadTrees message
  int max_receive_bytes = 64 << 20;  // largest message accepted from the server
  bool own_connection = false;       // a TCP connection not shared with same-target channels
  // Tries of a write call (CreateMap, DeleteMap, UploadTrees, Observe, RestoreVersion,
  // RemoveSource, PruneVersions) that timed out or lost its connection: every try carries the same
  // request id, so the server applies the write at most once (exactly-once writes).
  int write_attempts = 3;
  // Security (the server's side: docs/operations.md). TLS is on when `tls` or `tls_ca` is set.
  bool tls = false;      // TLS with the system's root certificates (unless tls_ca is set)
  std::string tls_ca;    // PEM file: CA that signed the server's certificate (implies TLS)
  std::string tls_cert;  // PEM file: client certificate, for servers that require one
  std::string tls_key;   // PEM file: key of tls_cert
  std::string token;     // bearer token sent with every call ("" : none)
  void Check() const;    // throws std::invalid_argument
};

// The channel credentials `options` ask for: plaintext, or TLS with its CA and client
// certificate. Throws std::runtime_error naming a file that cannot be read.
std::shared_ptr<grpc::ChannelCredentials> ChannelCredentialsFor(const ClientOptions& options);

// Where the sensor is about, for Relocalize: only poses within radius_m of (x, y) are searched.
struct PriorPosition {
  double x = 0;          // m, map frame
  double y = 0;          // m, map frame
  double radius_m = 10;  // m, the sensor is within this distance of (x, y)
};

// The maps a Relocalize searches: one map by `name`, or a set (relocalization.proto MapSet):
// the maps `names`, those matching `name_pattern` (a glob, "district-*"), or `all_readable`
// maps. The answer's map_name says which map the sensor was found in.
struct MapSelection {
  std::string name;
  std::vector<std::string> names;
  std::string name_pattern;
  bool all_readable = false;
};
// The set of `maps` for a request's `maps` field; nullopt when it names one map (`name`).
std::optional<v1::MapSet> MapSetOf(const MapSelection& maps);

// An axis-aligned box in the map frame (m).
struct Box2 {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;
};

struct ExportedTrees {
  std::vector<MapTreeRow> trees;  // by id
  std::vector<TreeState> states;  // states[i] belongs to trees[i]
  int64_t map_version = 0;        // the one version every tree comes from (0: no chunk sent)
  std::vector<algorithms::Polygon> boundary;  // the version's survey boundary (empty: none)
  // The order of the map's attribute columns (ExportTreesResponse.attribute_columns; empty: name
  // order), as ExportedAttributes (io/tree_columns.h) takes it.
  std::vector<std::string> attribute_columns;
};

// One frame for Observe: the trees detected in it (sensor frame) and, when known, its pose.
struct ObservedFrame {
  int64_t frame_id = 0;
  std::vector<algorithms::DetectedTree> trees;
  std::optional<algorithms::Pose3> map_from_sensor;  // absent: the server relocalizes the frame
  double position_sigma = 0;  // m, 1-sigma per horizontal axis of the pose (0: exact / unknown)
  double yaw_sigma = 0;       // rad
};

struct ObserveOptions {
  std::string source = "forestmap-cli";  // drone / upload id: [A-Za-z0-9_.:-], 1..128
  int64_t base_version = 0;              // the map version the data builds on (0: none)
  bool reject_stale = false;             // ABORTED unless the map is still at base_version
  double sensor_range = 0;               // m, for the evidence of absence (0: learned)
  double detection_probability = 0;      // near the sensor, in [0, 1) (0: learned)
  bool merge_only = false;               // merge without weighing the evidence of absence
};

// One frame of a tracking session.
struct TrackFrame {
  int64_t frame_id = 0;                         // echoed in the answer
  std::vector<algorithms::DetectedTree> trees;  // sensor frame; may be empty
  std::optional<Eigen::Vector3d> gravity;       // gravity (down) in the sensor frame
  std::optional<algorithms::Pose3> odometry;    // previous_sensor_from_sensor, when known
};

class ForestMapClient;

// A tracking session (the Track RPC), from ForestMapClient::Track: Step sends one frame and
// waits for its answer. Finish ends the session; the destructor cancels an unfinished one.
// Throws RpcError when the server ends the session with an error (bad frame, unknown map).
// The client must outlive the session.
class TrackSession {
 public:
  TrackSession(TrackSession&&) = default;
  ~TrackSession();

  v1::TrackResponse Step(const TrackFrame& frame);
  void Finish();

 private:
  friend class ForestMapClient;
  TrackSession(
      ForestMapClient& client, v1::TrackHeader header, std::unique_ptr<grpc::ClientContext> context,
      std::unique_ptr<grpc::ClientReaderWriter<v1::TrackRequest, v1::TrackResponse>> stream);

  ForestMapClient* client_;
  v1::TrackHeader header_;
  std::unique_ptr<grpc::ClientContext> context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::TrackRequest, v1::TrackResponse>> stream_;
  bool first_ = true;
};

// (trees sent so far, trees in total), called after each chunk of an upload.
// A survey boundary: polygons with holes in the map frame (m).
using Boundary = std::vector<algorithms::Polygon>;
using UploadProgress = std::function<void(int64_t sent, int64_t total)>;
using ExportProgress = std::function<void(int64_t received)>;

// Thread-compatible: one instance per thread, or external locking.
//
// Every call blocks until the server answers or the deadline passes (ClientOptions: call_timeout
// for a unary call, stream_timeout for a whole upload or export) and throws RpcError for any
// status but OK: code() for programs, what() for people. Writes are retried with one request id
// (applied at most once, ClientOptions::write_attempts); reads and Relocalize move to the next
// replica when one cannot be reached (see the constructor).
class ForestMapClient {
 public:
  // Creates the channel; does not connect yet. `address` is a gRPC target ("host:port"), or
  // several separated by commas ("a:1,b:2,c:3"): replicas of one service (forestmapd on one
  // PostgreSQL). Calls go to the first; when it cannot be reached (UNAVAILABLE, or no connection
  // before the deadline), idempotent calls (ListMaps, GetMap, ExportTrees, ListVersions,
  // Relocalize) are retried on the next replica, which then stays the current one. Writes and
  // Track are never retried: they fail with the replica's error. Throws std::invalid_argument
  // for options that fail ClientOptions::Check or no address, std::runtime_error for a TLS file
  // that cannot be read.
  explicit ForestMapClient(std::string address, const ClientOptions& options = {});

  const std::string& address() const { return address_; }
  // The replica calls currently go to.
  const std::string& current_address() const { return addresses_[current_]; }
  // Calls retried on another replica so far.
  int64_t retries() const { return retries_; }

  v1::Map CreateMap(const std::string& name, const std::string& description = "",
                    const std::string& crs = "");
  std::vector<v1::Map> ListMaps();
  v1::Map GetMap(const std::string& name);
  void DeleteMap(const std::string& name);

  // Streams the rows in chunks; the server applies them in one transaction at the end.
  // `boundary` set: the map's survey boundary from the new version on (map frame; empty removes
  // it); unset: the map keeps its boundary. `columns`: the file's attribute columns in its order
  // (TreeFile::attribute_columns), which exports keep; empty: the map keeps its order.
  v1::UploadTreesResponse UploadTrees(const std::string& name, const std::vector<MapTreeRow>& rows,
                                      bool replace, const UploadProgress& progress = {},
                                      const std::optional<Boundary>& boundary = std::nullopt,
                                      const std::vector<std::string>& columns = {});
  // Creates the map and uploads its trees in one upload stream (create_map): the map exists only
  // if the whole upload succeeds. ALREADY_EXISTS when the map exists.
  v1::UploadTreesResponse CreateMapWithTrees(const std::string& name,
                                             const std::string& description, const std::string& crs,
                                             const std::vector<MapTreeRow>& rows,
                                             const UploadProgress& progress = {},
                                             const std::optional<Boundary>& boundary = std::nullopt,
                                             const std::vector<std::string>& columns = {});

  // `version` 0: the current version; else an older one (see ListVersions). `progress` gets the
  // count of trees received after each message.
  ExportedTrees ExportTrees(const std::string& name, const std::optional<Box2>& box = {},
                            int64_t version = 0, const ExportProgress& progress = {});

  // Shared maps. One Observe call is one request (one new version); batch large sequences.
  v1::ObserveResponse Observe(const std::string& name, const std::vector<ObservedFrame>& frames,
                              const ObserveOptions& options);
  std::vector<v1::MapVersion> ListVersions(const std::string& name, int limit = 0);
  v1::Map RestoreVersion(const std::string& name, int64_t version);
  v1::RemoveSourceResponse RemoveSource(const std::string& name, const std::string& source);
  // Keeps the newest `keep` versions readable, drops the older history.
  v1::PruneVersionsResponse PruneVersions(const std::string& name, int64_t keep);

  // A tracking session in map `name` (no deadline: it lasts as long as the flight).
  TrackSession Track(const std::string& name);
  // A session over a set of maps (or one, `maps.name`): it crosses from one map into the next;
  // each answer's result().map_name() names its map.
  TrackSession Track(const MapSelection& maps);

  // `gravity`: direction of gravity (down) in the sensor frame, when known.
  v1::RelocalizeResponse Relocalize(const std::string& name,
                                    const std::vector<algorithms::DetectedTree>& trees,
                                    const std::optional<PriorPosition>& prior = {},
                                    const std::optional<Eigen::Vector3d>& gravity = {});
  // The same over a set of maps (or one map, `maps.name`).
  v1::RelocalizeResponse Relocalize(const MapSelection& maps,
                                    const std::vector<algorithms::DetectedTree>& trees,
                                    const std::optional<PriorPosition>& prior = {},
                                    const std::optional<Eigen::Vector3d>& gravity = {});

 private:
  friend class TrackSession;
  // Waits (once) for the channel to connect; a failure is remembered so that the first call,
  // which then fails fast, is reported as "cannot reach".
  void EnsureConnected();
  std::unique_ptr<grpc::ClientContext> NewContext(double timeout);
  // Throws RpcError for a non-OK status of the call named `call`.
  void Check(const grpc::Status& status, const char* call) const;
  // One unary RPC with the call timeout: `(stub->*method)(context, request, &response)`.
  template <typename Response, typename Method, typename Request>
  Response Unary(Method method, const Request& request, const char* call);
  // Runs `call` and, while it fails because the replica cannot be reached, again on the next
  // replica (each replica once).
  template <typename Call>
  auto WithFailover(const Call& call) -> decltype(call());
  ExportedTrees ExportTreesOnce(const v1::ExportTreesRequest& request,
                                const ExportProgress& progress);
  // A write RPC: `attempt(request_id)` makes one try and returns its status; tries again with
  // the same id (up to write_attempts) after DEADLINE_EXCEEDED or UNAVAILABLE.
  void WriteWithRetries(const std::function<grpc::Status(const std::string&)>& attempt,
                        const char* call);
  template <typename Response, typename Method, typename Request>
  Response UnaryWrite(Method method, Request request, const char* call);
  // One try of an upload stream (the header, then chunks of rows); the status of the call.
  grpc::Status UploadOnce(const v1::UploadTreesHeader& header, const std::vector<MapTreeRow>& rows,
                          const UploadProgress& progress, v1::UploadTreesResponse& response);
  // The upload with retries; each try's header gets the same request id.
  v1::UploadTreesResponse Upload(v1::UploadTreesHeader header, const std::vector<MapTreeRow>& rows,
                                 const UploadProgress& progress);

  std::string address_;
  ClientOptions options_;
  std::vector<std::string> addresses_;  // the replicas, in the order given
  std::vector<std::shared_ptr<grpc::Channel>> channels_;
  std::vector<std::unique_ptr<v1::ForestMap::Stub>> stubs_;
  size_t current_ = 0;
  int64_t retries_ = 0;
  std::shared_ptr<grpc::Channel> channel_;  // channels_[current_]
  v1::ForestMap::Stub* stub_ = nullptr;     // stubs_[current_]
  bool connect_checked_ = false;
  bool connected_ = false;
};

using forestmap::StatusCodeName;  // proto/status_code_name.h

}  // namespace forestmap::client
