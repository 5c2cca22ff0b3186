#pragma once
// Validation of every request of the ForestMap API, before anything is converted or stored.
//
// Each function throws ValidationError (INVALID_ARGUMENT, naming the field for the error
// details) or LimitError (RESOURCE_EXHAUSTED) from server/app/errors.h, with a message naming
// the field path and index, e.g.
//   "trees[12].position.x is NaN"
//   "prior.radius_m is -1; it must be > 0"
//   "trees: 100000 trees exceed the limit of 20000 per query"
// Rules beyond "finite numbers": dbh in [0, kMaxDbh], score in [0, 1], tree ids >= 0 and unique
// within an upload, rotations unit quaternions within kUnitQuaternionTolerance (normalised
// afterwards), prior radius > 0, gravity and stem axes non-zero, box min <= max, bounded string
// lengths, coordinates within kMaxHorizontalCoordinate / kMaxVerticalCoordinate.

#include <google/protobuf/repeated_ptr_field.h>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/observations.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "forestmap/v1/tracking.pb.h"
#include "server/app/errors.h"
#include "server/app/limits.h"

namespace forestmap::server {

inline constexpr double kUnitQuaternionTolerance = 1e-3;  // | |q| - 1 | allowed
// A map frame is a local frame (georeferenced offsets belong in the CRS): every coordinate that
// reaches an index (trees, detected trees, poses, priors, odometry) must lie strictly within
// these bounds, or the request is INVALID_ARGUMENT naming the field.
inline constexpr double kMaxHorizontalCoordinate = 1e7;   // m, |x| and |y|
inline constexpr double kMaxVerticalCoordinate = 1e5;     // m, |z|
inline constexpr double kMaxDbh = 100;                    // m; no stem is thicker
inline constexpr double kMaxSensorRange = 1000;           // m, a stated range or pose sigma
inline constexpr size_t kMaxDescriptionLength = 4096;     // bytes
inline constexpr size_t kMaxCrsLength = 16384;            // bytes
inline constexpr size_t kMaxAttributes = 64;              // per tree
inline constexpr size_t kMaxAttributeKeyLength = 128;     // bytes
inline constexpr size_t kMaxAttributeValueLength = 4096;  // bytes

// A user-supplied string made safe to quote in an error message: printable ASCII, bounded.
std::string Quoted(const std::string& s);
// A field path of a repeated field's element: Indexed("trees", 12) is "trees[12]".
std::string Indexed(std::string_view field, int64_t index);

// `field` is the path to report, e.g. "name" or "header.name".
void ValidateMapName(const std::string& name, std::string_view field);

inline constexpr size_t kMaxNamePatternLength = 256;  // bytes of MapSet.name_pattern

// A set (RelocalizeRequest.maps, TrackHeader.maps): the message's `name` empty beside it,
// exactly one of names (valid names, no duplicates, at most `max_query_maps`: else
// RESOURCE_EXHAUSTED), name_pattern (1..kMaxNamePatternLength bytes) or all_readable. Throws
// ValidationError naming the field (`prefix` + "maps.names[2]"), LimitError.
void ValidateMapSet(const v1::MapSet& set, const std::string& name, const std::string& prefix,
                    int max_query_maps);

void Validate(const v1::CreateMapRequest& request);
void Validate(const v1::GetMapRequest& request);
void Validate(const v1::DeleteMapRequest& request);
void Validate(const v1::ExportTreesRequest& request);
// With `maps` set (a question over many maps), the set as ValidateMapSet (above).
void Validate(const v1::RelocalizeRequest& request, int max_query_trees,
              int max_query_maps = kDefaultMaxQueryMaps);
// A prior: x and y, or the deprecated pose of release 0.1.0 (not both); radius_m > 0.
void ValidatePrior(const v1::PriorPose& prior, const std::string& path);

// One message of a Track stream, in either layout (server/grpc/legacy_layout.h), checked: a header
// first, then frames of any number of trees up to the limit. `session_map` is the map the first
// message named ("" while reading that one; kSetSession after a header naming a set of maps).
inline constexpr const char* kSetSession = "*";  // never a map name
struct TrackMessage {
  std::string map;                      // the map a first message names ("" on later ones)
  std::optional<v1::MapSet> maps;       // or the set of maps a header names (ValidateMapSet)
  std::optional<v1::TrackFrame> frame;  // the frame to answer; none for a header
};
TrackMessage ReadTrackMessage(v1::TrackRequest& request, const std::string& session_map,
                              int max_query_trees, int max_query_maps = kDefaultMaxQueryMaps);

// Shared maps (observations.proto).
inline constexpr size_t kMaxSourceLength = 128;         // bytes
inline constexpr const char* kSurveySource = "survey";  // reserved for survey priors
struct ObserveLimits {
  int max_frames = 200;             // frames per Observe request
  int max_frame_trees = 2'000;      // detected trees per frame
  int max_request_trees = 100'000;  // detected trees per request
};
// A source id: 1..128 characters of [A-Za-z0-9_.:-], not "survey". `field` names it.
void ValidateSource(const std::string& source, std::string_view field);
void Validate(const v1::ObserveRequest& request, const ObserveLimits& limits);
void Validate(const v1::ListVersionsRequest& request);
void Validate(const v1::RestoreVersionRequest& request);
void Validate(const v1::RemoveSourceRequest& request);

// The one rule set of a tree as a map stores it (map frame), for every write path: upload (its
// trees), Observe (a frame's trees placed by its pose): x, y within kMaxHorizontalCoordinate, z
// within kMaxVerticalCoordinate, dbh in [0, kMaxDbh]. Absent values are not checked. The error
// names `path`.x (etc.); with `frame` set ("in the map frame") it names `path` and says "`path`
// in the map frame: z is ...".
void CheckMapTree(double x, double y, std::optional<double> z, std::optional<double> dbh,
                  const std::string& path, std::string_view frame = {});

// Pieces, exposed for tests and for the upload stream. `path` prefixes the messages.
void ValidateTree(const v1::Tree& tree, const std::string& path);
void ValidateDetectedTree(const v1::DetectedTree& tree, const std::string& path);
void ValidatePose(const v1::Pose& pose, const std::string& path);
void ValidateBox(const v1::Box2& box, const std::string& path);
// A survey boundary: rings of at least 3 vertices within kMaxHorizontalCoordinate, at most
// kMaxBoundaryVertices vertices in all (the store checks the rest: storage/boundary_json.h).
inline constexpr int64_t kMaxBoundaryVertices = 100000;
void ValidateBoundary(const v1::SurveyBoundary& boundary, const std::string& path);
// The attribute columns of an upload's file: keys as for a tree's attributes, each once, at most
// as many as a tree may have.
void ValidateAttributeColumns(const google::protobuf::RepeatedPtrField<std::string>& names,
                              const std::string& path);

}  // namespace forestmap::server
