#include "server/validation.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "storage/map_store.h"

namespace forestmap::server {
namespace {

std::string Number(double v) {
  std::ostringstream out;
  out.precision(10);
  out << v;
  return out.str();
}

// A user-supplied string made safe to quote in an error message: printable ASCII, bounded.
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

void CheckFinite(double v, const std::string& path) {
  if (std::isnan(v)) throw ValidationError(path + " is NaN; numbers must be finite");
  if (std::isinf(v)) {
    throw ValidationError(path + " is " + (v > 0 ? "+inf" : "-inf") + "; numbers must be finite");
  }
}

void CheckVector(const v1::Vector3& v, const std::string& path) {
  CheckFinite(v.x(), path + ".x");
  CheckFinite(v.y(), path + ".y");
  CheckFinite(v.z(), path + ".z");
}

// A direction: finite and not (near) zero. Its length does not matter, it is normalised.
void CheckDirection(const v1::Vector3& v, const std::string& path) {
  CheckVector(v, path);
  constexpr double kMinNorm = 1e-9;
  if (std::sqrt(v.x() * v.x() + v.y() * v.y() + v.z() * v.z()) < kMinNorm) {
    throw ValidationError(path + " is a zero vector; it must give a direction");
  }
}

void CheckLength(const std::string& s, size_t max_length, const std::string& path) {
  if (s.size() > max_length) {
    throw ValidationError(path + ": " + std::to_string(s.size()) + " bytes exceed the limit of " +
                          std::to_string(max_length));
  }
}

void CheckAttributes(const v1::Tree& tree, const std::string& path) {
  const std::string field = path + ".attributes";
  if (static_cast<size_t>(tree.attributes_size()) > kMaxAttributes) {
    throw ValidationError(field + ": " + std::to_string(tree.attributes_size()) +
                          " attributes exceed the limit of " + std::to_string(kMaxAttributes));
  }
  for (const auto& [key, value] : tree.attributes()) {
    if (key.empty()) throw ValidationError(field + " has an empty key");
    CheckLength(key, kMaxAttributeKeyLength, field + " key " + Quoted(key));
    CheckLength(value, kMaxAttributeValueLength, field + "[" + Quoted(key) + "]");
  }
}

}  // namespace

void ValidateMapName(const std::string& name, std::string_view field) {
  const std::string problem = storage::ValidateMapName(name);
  if (!problem.empty()) {
    throw ValidationError(std::string(field) + " " + Quoted(name) + ": " + problem);
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
  ValidateMapName(request.map_name(), "map_name");
  if (request.has_box()) ValidateBox(request.box(), "box");
}

void Validate(const v1::RelocalizeRequest& request, int max_query_trees) {
  ValidateMapName(request.map_name(), "map_name");
  const int n = request.trees_size();
  if (n < kMinQueryTrees) {
    throw ValidationError("trees: a relocalization needs at least " +
                          std::to_string(kMinQueryTrees) + " trees, got " + std::to_string(n));
  }
  if (n > max_query_trees) {
    throw LimitError("trees: " + std::to_string(n) + " trees exceed the limit of " +
                     std::to_string(max_query_trees) + " per query");
  }
  for (int i = 0; i < n; ++i) ValidateDetectedTree(request.trees(i), Indexed("trees", i));
  if (request.has_prior()) {
    const v1::PriorPose& prior = request.prior();
    if (!prior.has_map_from_sensor()) {
      throw ValidationError("prior.map_from_sensor is missing; a prior needs a pose");
    }
    ValidatePose(prior.map_from_sensor(), "prior.map_from_sensor");
    CheckFinite(prior.radius_m(), "prior.radius_m");
    if (prior.radius_m() <= 0) {
      throw ValidationError("prior.radius_m is " + Number(prior.radius_m()) + "; it must be > 0");
    }
  }
  if (request.has_gravity()) CheckDirection(request.gravity(), "gravity");
}

void ValidateTree(const v1::Tree& tree, const std::string& path) {
  if (tree.has_id() && tree.id() < 0) {
    throw ValidationError(path + ".id is " + std::to_string(tree.id()) + "; ids must be >= 0");
  }
  CheckFinite(tree.x(), path + ".x");
  CheckFinite(tree.y(), path + ".y");
  if (tree.has_z()) CheckFinite(tree.z(), path + ".z");
  if (tree.has_dbh()) {
    CheckFinite(tree.dbh(), path + ".dbh");
    if (tree.dbh() < 0) {
      throw ValidationError(path + ".dbh is " + Number(tree.dbh()) + "; it must be >= 0");
    }
  }
  CheckAttributes(tree, path);
}

void ValidateDetectedTree(const v1::DetectedTree& tree, const std::string& path) {
  if (!tree.has_position()) throw ValidationError(path + ".position is missing");
  CheckVector(tree.position(), path + ".position");
  if (tree.has_dbh()) {
    CheckFinite(tree.dbh(), path + ".dbh");
    if (tree.dbh() < 0) {
      throw ValidationError(path + ".dbh is " + Number(tree.dbh()) + "; it must be >= 0");
    }
  }
  if (tree.has_axis()) CheckDirection(tree.axis(), path + ".axis");
  if (tree.has_score()) {
    CheckFinite(tree.score(), path + ".score");
    if (tree.score() < 0 || tree.score() > 1) {
      throw ValidationError(path + ".score is " + Number(tree.score()) + "; it must be in [0, 1]");
    }
  }
}

void ValidatePose(const v1::Pose& pose, const std::string& path) {
  if (pose.has_translation()) CheckVector(pose.translation(), path + ".translation");
  if (!pose.has_rotation()) return;  // identity
  const v1::Quaternion& q = pose.rotation();
  const std::string rotation = path + ".rotation";
  CheckFinite(q.x(), rotation + ".x");
  CheckFinite(q.y(), rotation + ".y");
  CheckFinite(q.z(), rotation + ".z");
  CheckFinite(q.w(), rotation + ".w");
  const double norm = std::sqrt(q.x() * q.x() + q.y() * q.y() + q.z() * q.z() + q.w() * q.w());
  if (std::abs(norm - 1.0) > kUnitQuaternionTolerance) {
    throw ValidationError(rotation + " is not a unit quaternion (norm " + Number(norm) +
                          "); normalise it");
  }
}

void ValidateBox(const v1::Box2& box, const std::string& path) {
  CheckFinite(box.min_x(), path + ".min_x");
  CheckFinite(box.min_y(), path + ".min_y");
  CheckFinite(box.max_x(), path + ".max_x");
  CheckFinite(box.max_y(), path + ".max_y");
  if (box.min_x() > box.max_x() || box.min_y() > box.max_y()) {
    throw ValidationError(path + " is empty: min_x <= max_x and min_y <= max_y are required");
  }
}

void UploadValidator::Accept(const v1::UploadTreesRequest& message) {
  const std::string where = " (upload message " + std::to_string(messages_) + ")";
  if (messages_ == 0) {
    if (message.map_name().empty()) {
      throw ValidationError("map_name: the first message of an upload must name the map");
    }
    ValidateMapName(message.map_name(), "map_name");
    map_name_ = message.map_name();
    replace_ = message.replace();
  } else {
    if (!message.map_name().empty() && message.map_name() != map_name_) {
      throw ValidationError("map_name: " + Quoted(message.map_name()) + where +
                            " differs from the upload's map " + Quoted(map_name_));
    }
    if (message.replace() && !replace_) {
      throw ValidationError("replace" + where + ": only the first message may set replace");
    }
  }
  ++messages_;
  if (message.trees_size() > max_trees_ - trees_) {
    throw LimitError("trees: the upload exceeds the limit of " + std::to_string(max_trees_) +
                     " trees per stream");
  }
  for (const v1::Tree& tree : message.trees()) {
    const int64_t index = trees_++;
    const std::string path = Indexed("trees", index);
    ValidateTree(tree, path);
    if (!tree.has_id()) continue;
    const auto [it, inserted] = index_of_id_.emplace(tree.id(), index);
    if (!inserted) {
      throw ValidationError(path + ".id " + std::to_string(tree.id()) + " duplicates " +
                            Indexed("trees", it->second) + ".id" + where);
    }
  }
}

void UploadValidator::Finish() const {
  if (messages_ == 0) {
    throw ValidationError(
        "map_name: the upload stream was empty; its first message must name "
        "the map");
  }
}

}  // namespace forestmap::server
