#include "server/grpc/validation.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>
#include <tuple>

#include "server/grpc/legacy_layout.h"
#include "server/grpc/validation_fields.h"
#include "storage/map_store.h"

namespace forestmap::server {
namespace {

// The trees of a frame with a pose as they land in the map: within the bounds of a map's trees
// (CheckMapTree), like the trees of an upload.
void CheckTreesInMapFrame(const v1::ObservationFrame& frame, const std::string& path) {
  const v1::Pose& pose = frame.map_from_sensor();
  const v1::Quaternion& q = pose.rotation();
  const Eigen::Quaterniond rotation =
      pose.has_rotation() ? Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z()).normalized()
                          : Eigen::Quaterniond::Identity();
  const v1::Vector3& t = pose.translation();
  for (int i = 0; i < frame.trees_size(); ++i) {
    const v1::Vector3& p = frame.trees(i).position();
    const Eigen::Vector3d in_map =
        rotation * Eigen::Vector3d(p.x(), p.y(), p.z()) + Eigen::Vector3d(t.x(), t.y(), t.z());
    CheckMapTree(in_map.x(), in_map.y(), in_map.z(), std::nullopt, path + "." + Indexed("trees", i),
                 "in the map frame");
  }
}

void CheckLength(const std::string& s, size_t max_length, const std::string& path) {
  if (s.size() > max_length) {
    throw ValidationError(path, ": " + std::to_string(s.size()) + " bytes exceed the limit of " +
                                    std::to_string(max_length));
  }
}

// Columns unknown for this tree: keys as for attributes, none also a key of `attributes`, and
// counted with them in the per-tree limit.
void CheckNullAttributes(const v1::Tree& tree, const std::string& path) {
  const std::string field = path + ".null_attributes";
  const size_t count = static_cast<size_t>(tree.attributes_size() + tree.null_attributes_size());
  if (count > kMaxAttributes) {
    throw ValidationError(field, ": " + std::to_string(count) +
                                     " attributes and null attributes exceed the limit of " +
                                     std::to_string(kMaxAttributes));
  }
  for (const std::string& key : tree.null_attributes()) {
    if (key.empty()) throw ValidationError(field, " has an empty key");
    CheckLength(key, kMaxAttributeKeyLength, field + " key " + Quoted(key));
    if (tree.attributes().count(key) != 0) {
      throw ValidationError(field, ": " + Quoted(key) + " is also a key of attributes");
    }
  }
}

void CheckAttributes(const v1::Tree& tree, const std::string& path) {
  const std::string field = path + ".attributes";
  if (static_cast<size_t>(tree.attributes_size()) > kMaxAttributes) {
    throw ValidationError(field, ": " + std::to_string(tree.attributes_size()) +
                                     " attributes exceed the limit of " +
                                     std::to_string(kMaxAttributes));
  }
  for (const auto& [key, value] : tree.attributes()) {
    if (key.empty()) throw ValidationError(field, " has an empty key");
    CheckLength(key, kMaxAttributeKeyLength, field + " key " + Quoted(key));
    CheckLength(value, kMaxAttributeValueLength, field + "[" + Quoted(key) + "]");
  }
  CheckNullAttributes(tree, path);
}

}  // namespace

std::string Quoted(const std::string& s) {
  constexpr size_t kMaxShown = 48;
  std::string out = "\"";
  for (size_t i = 0; i < s.size() && i < kMaxShown; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7f && c != '"' && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02x", c);
      out += escaped;
    }
  }
  if (s.size() > kMaxShown) out += "...";
  return out + "\"";
}

std::string Indexed(std::string_view field, int64_t index) {
  return std::string(field) + "[" + std::to_string(index) + "]";
}

void ValidateMapName(const std::string& name, std::string_view field) {
  const std::string problem = storage::ValidateMapName(name);
  if (!problem.empty()) {
    throw ValidationError(std::string(field), " " + Quoted(name) + ": " + problem);
  }
}

void Validate(const v1::CreateMapRequest& request) {
  ValidateMapName(request.name(), "name");
  CheckLength(request.description(), kMaxDescriptionLength, "description");
  CheckLength(request.crs(), kMaxCrsLength, "crs");
}

void Validate(const v1::GetMapRequest& request) { ValidateMapName(request.name(), "name"); }

void Validate(const v1::DeleteMapRequest& request) { ValidateMapName(request.name(), "name"); }

void Validate(const v1::ExportTreesRequest& request) {
  ValidateMapName(request.name(), "name");
  if (request.has_box()) ValidateBox(request.box(), "box");
  if (request.version() < 0) {
    throw ValidationError("version", " is " + std::to_string(request.version()) +
                                         "; it must be >= 1, or 0 for the current version");
  }
}

void ValidateSource(const std::string& source, std::string_view field) {
  const std::string path(field);
  if (source.empty()) throw ValidationError(path, " is empty; name the drone or upload");
  CheckLength(source, kMaxSourceLength, path);
  for (size_t i = 0; i < source.size(); ++i) {
    const char c = source[i];
    const bool allowed = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
                         (c >= '0' && c <= '9') || c == '_' || c == '.' || c == '-' || c == ':';
    if (!allowed) {
      throw ValidationError(path, " " + Quoted(source) +
                                      ": only A-Z a-z 0-9 _ . : - are allowed (character " +
                                      std::to_string(i + 1) + " is not)");
    }
  }
  if (source == kSurveySource) {
    throw ValidationError(path, " \"survey\" is reserved for surveyed trees");
  }
}

void Validate(const v1::ObserveRequest& request, const ObserveLimits& limits) {
  ValidateMapName(request.name(), "name");
  ValidateSource(request.source(), "source");
  if (request.base_version() < 0) {
    throw ValidationError("base_version",
                          " is " + std::to_string(request.base_version()) + "; it must be >= 0");
  }
  if (request.conflict_policy() == v1::CONFLICT_POLICY_REJECT_IF_STALE &&
      request.base_version() == 0) {
    throw ValidationError("base_version",
                          ": REJECT_IF_STALE needs the version the data is based on");
  }
  if (!v1::ConflictPolicy_IsValid(request.conflict_policy())) {
    throw ValidationError("conflict_policy",
                          " " + std::to_string(request.conflict_policy()) + " is unknown");
  }
  if (!(request.sensor_range() >= 0 && request.sensor_range() <= kMaxSensorRange)) {
    throw ValidationError("sensor_range", " is " + std::to_string(request.sensor_range()) +
                                              "; it must be in [0, " +
                                              std::to_string(int(kMaxSensorRange)) + "] m");
  }
  if (!(request.detection_probability() >= 0 && request.detection_probability() < 1)) {
    throw ValidationError("detection_probability",
                          " is " + std::to_string(request.detection_probability()) +
                              "; it must be in [0, 1) (0: learned)");
  }
  const int frames = request.frames_size();
  if (frames == 0) throw ValidationError("frames", ": an observation needs at least one frame");
  if (frames > limits.max_frames) {
    throw LimitError("frames: " + std::to_string(frames) + " frames exceed the limit of " +
                     std::to_string(limits.max_frames) + " per request; send them in batches");
  }
  int64_t total = 0;
  std::unordered_map<int64_t, int> index_of_frame;
  for (int f = 0; f < frames; ++f) {
    const v1::ObservationFrame& frame = request.frames(f);
    const std::string path = Indexed("frames", f);
    const auto [it, inserted] = index_of_frame.emplace(frame.frame_id(), f);
    if (!inserted) {
      throw ValidationError(path + ".frame_id", " " + std::to_string(frame.frame_id()) +
                                                    " duplicates " + Indexed("frames", it->second) +
                                                    ".frame_id");
    }
    if (frame.trees_size() > limits.max_frame_trees) {
      throw LimitError(path + ".trees: " + std::to_string(frame.trees_size()) +
                       " trees exceed the limit of " + std::to_string(limits.max_frame_trees) +
                       " per frame");
    }
    total += frame.trees_size();
    if (total > limits.max_request_trees) {
      throw LimitError("frames: more than " + std::to_string(limits.max_request_trees) +
                       " trees in one request; send fewer frames per request");
    }
    for (int i = 0; i < frame.trees_size(); ++i) {
      ValidateDetectedTree(frame.trees(i), path + "." + Indexed("trees", i));
    }
    if (frame.has_map_from_sensor()) {
      ValidatePose(frame.map_from_sensor(), path + ".map_from_sensor");
      CheckTreesInMapFrame(frame, path);
    }
    if (frame.has_gravity()) CheckDirection(frame.gravity(), path + ".gravity");
    for (const auto& [field, value, max] :
         {std::tuple{".position_sigma", frame.position_sigma(), kMaxSensorRange},
          std::tuple{".yaw_sigma", frame.yaw_sigma(), 3.15}}) {
      if (!(value >= 0 && value <= max)) {
        throw ValidationError(path + field, " is " + std::to_string(value) +
                                                "; it must be in [0, " + std::to_string(max) + "]");
      }
    }
  }
}

void Validate(const v1::ListVersionsRequest& request) {
  ValidateMapName(request.name(), "name");
  if (request.limit() < 0) {
    throw ValidationError("limit", " is " + std::to_string(request.limit()) + "; it must be >= 0");
  }
}

void Validate(const v1::RestoreVersionRequest& request) {
  ValidateMapName(request.name(), "name");
  if (request.version() < 1) {
    throw ValidationError("version",
                          " is " + std::to_string(request.version()) + "; it must be >= 1");
  }
}

void Validate(const v1::RemoveSourceRequest& request) {
  ValidateMapName(request.name(), "name");
  ValidateSource(request.source(), "source");
}

void ValidateMapSet(const v1::MapSet& set, const std::string& name, const std::string& prefix,
                    int max_query_maps) {
  if (!name.empty()) {
    throw ValidationError(prefix + "name", " is set beside maps; name one map, or a set in maps");
  }
  const int ways = (set.names_size() > 0) + !set.name_pattern().empty() + set.all_readable();
  if (ways != 1) {
    throw ValidationError(prefix + "maps",
                          ways == 0 ? " is empty; give names, name_pattern or all_readable"
                                    : " sets more than one of names, name_pattern and "
                                      "all_readable; give one");
  }
  if (set.names_size() > max_query_maps) {
    throw LimitError(prefix + "maps.names: " + std::to_string(set.names_size()) +
                     " maps exceed the limit of " + std::to_string(max_query_maps) +
                     " per question");
  }
  std::set<std::string> seen;
  for (int i = 0; i < set.names_size(); ++i) {
    const std::string field = Indexed(prefix + "maps.names", i);
    ValidateMapName(set.names(i), field);
    if (!seen.insert(set.names(i)).second) {
      throw ValidationError(field, " names " + Quoted(set.names(i)) + " a second time");
    }
  }
  if (set.name_pattern().size() > kMaxNamePatternLength) {
    throw ValidationError(prefix + "maps.name_pattern",
                          " is longer than " + std::to_string(kMaxNamePatternLength) + " bytes");
  }
}

void Validate(const v1::RelocalizeRequest& request, int max_query_trees, int max_query_maps) {
  if (request.has_maps()) {
    ValidateMapSet(request.maps(), request.name(), "", max_query_maps);
  } else {
    ValidateMapName(request.name(), "name");
  }
  const int n = request.trees_size();  // fewer than 3: answered NOT_FOUND (TOO_FEW_TREES)
  if (n > max_query_trees) {
    throw LimitError("trees: " + std::to_string(n) + " trees exceed the limit of " +
                     std::to_string(max_query_trees) + " per query");
  }
  for (int i = 0; i < n; ++i) ValidateDetectedTree(request.trees(i), Indexed("trees", i));
  if (request.has_prior()) ValidatePrior(request.prior(), "prior");
  if (request.has_gravity()) CheckDirection(request.gravity(), "gravity");
}

void ValidatePrior(const v1::PriorPose& prior, const std::string& path) {
  if (const v1::Pose* pose = LegacyPose(prior)) {  // the 0.1.0 form
    if (prior.has_x() || prior.has_y()) {
      throw ValidationError(path + ".map_from_sensor",
                            " is set beside " + path +
                                ".x and .y; give x and y only (the pose "
                                "is the deprecated form of the same prior)");
    }
    ValidatePose(*pose, path + ".map_from_sensor");
  } else {
    for (const auto& [has, value, name] :
         {std::tuple{prior.has_x(), prior.x(), ".x"}, std::tuple{prior.has_y(), prior.y(), ".y"}}) {
      if (!has) {
        throw ValidationError(path + name,
                              " is missing; a prior is the sensor's horizontal position (x, y)");
      }
      CheckCoordinate(value, kMaxHorizontalCoordinate, path + name);
    }
  }
  CheckFinite(prior.radius_m(), path + ".radius_m");
  if (prior.radius_m() <= 0) {
    throw ValidationError(path + ".radius_m",
                          " is " + Number(prior.radius_m()) + "; it must be > 0");
  }
}

TrackMessage ReadTrackMessage(v1::TrackRequest& request, const std::string& session_map,
                              int max_query_trees, int max_query_maps) {
  if (HasLegacyFields(request) && request.part_case() != v1::TrackRequest::PART_NOT_SET) {
    throw ValidationError(request.has_header() ? "header" : "frame", kMixedLayouts);
  }
  TrackMessage message;
  std::string prefix;  // of the frame's field paths
  if (request.has_header()) {
    if (!session_map.empty()) {
      throw ValidationError("header", ": only the first message of a Track stream is a header");
    }
    if (request.header().has_maps()) {
      ValidateMapSet(request.header().maps(), request.header().name(), "header.", max_query_maps);
      message.maps = request.header().maps();
      return message;
    }
    message.map = request.header().name();
    ValidateMapName(message.map, "header.name");
    return message;
  }
  if (request.has_frame()) {
    if (session_map.empty()) {
      throw ValidationError("header",
                            " is missing: the first message of a Track stream names the map");
    }
    message.frame = std::move(*request.mutable_frame());
    prefix = "frame.";
  } else {  // the 0.1.0 layout: every message is a frame, the first also names the map
    const std::string name = LegacyHeader(request).name();
    if (session_map.empty()) {
      ValidateMapName(name, "name");
      message.map = name;
    } else if (!name.empty() && name != session_map) {
      throw ValidationError("name", " " + Quoted(name) + " differs from the session's map " +
                                        Quoted(session_map) + "; a session tracks in one map");
    }
    message.frame = TakeLegacyFrame(request);
  }
  const v1::TrackFrame& frame = *message.frame;
  const int n = frame.trees_size();
  if (n > max_query_trees) {
    throw LimitError(prefix + "trees: " + std::to_string(n) + " trees exceed the limit of " +
                     std::to_string(max_query_trees) + " per frame");
  }
  for (int i = 0; i < n; ++i) ValidateDetectedTree(frame.trees(i), prefix + Indexed("trees", i));
  if (frame.has_gravity()) CheckDirection(frame.gravity(), prefix + "gravity");
  if (frame.has_odometry()) ValidatePose(frame.odometry(), prefix + "odometry");
  return message;
}

void CheckMapTree(double x, double y, std::optional<double> z, std::optional<double> dbh,
                  const std::string& path, std::string_view frame) {
  for (const auto& [name, value, limit] :
       {std::tuple{"x", std::optional(x), kMaxHorizontalCoordinate},
        std::tuple{"y", std::optional(y), kMaxHorizontalCoordinate},
        std::tuple{"z", z, kMaxVerticalCoordinate}}) {
    if (!value) continue;
    const std::string problem = CoordinateProblem(*value, limit);
    if (problem.empty()) continue;
    if (frame.empty()) throw ValidationError(path + "." + name, " is " + problem);
    throw ValidationError(path, " " + std::string(frame) + ": " + name + " is " + problem);
  }
  if (dbh) CheckDbh(*dbh, path + ".dbh");
}

void ValidateTree(const v1::Tree& tree, const std::string& path) {
  if (tree.has_id() && tree.id() < 0) {
    throw ValidationError(path + ".id", " is " + std::to_string(tree.id()) + "; ids must be >= 0");
  }
  CheckMapTree(tree.x(), tree.y(), tree.has_z() ? std::optional(tree.z()) : std::nullopt,
               tree.has_dbh() ? std::optional(tree.dbh()) : std::nullopt, path);
  CheckAttributes(tree, path);
}

void ValidateDetectedTree(const v1::DetectedTree& tree, const std::string& path) {
  if (!tree.has_position()) throw ValidationError(path + ".position", " is missing");
  CheckPosition(tree.position(), path + ".position");
  if (tree.has_dbh()) CheckDbh(tree.dbh(), path + ".dbh");
  if (tree.has_axis()) CheckDirection(tree.axis(), path + ".axis");
  if (tree.has_score()) {
    CheckFinite(tree.score(), path + ".score");
    if (tree.score() < 0 || tree.score() > 1) {
      throw ValidationError(path + ".score",
                            " is " + Number(tree.score()) + "; it must be in [0, 1]");
    }
  }
}

void ValidateAttributeColumns(const google::protobuf::RepeatedPtrField<std::string>& names,
                              const std::string& path) {
  if (static_cast<size_t>(names.size()) > kMaxAttributes) {
    throw ValidationError(path, ": " + std::to_string(names.size()) +
                                    " columns exceed the limit of " +
                                    std::to_string(kMaxAttributes));
  }
  std::set<std::string> seen;
  for (const std::string& name : names) {
    if (name.empty()) throw ValidationError(path, " has an empty name");
    CheckLength(name, kMaxAttributeKeyLength, path + " name " + Quoted(name));
    if (!seen.insert(name).second) throw ValidationError(path, ": " + Quoted(name) + " is twice");
  }
}

}  // namespace forestmap::server
