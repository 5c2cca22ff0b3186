#include "server/convert.h"

namespace forestmap::server {
namespace {

// Normalises a direction; a (near) zero vector stays zero, meaning "unknown".
Eigen::Vector3d Direction(const Eigen::Vector3d& v) {
  const double norm = v.norm();
  return norm > 0 ? Eigen::Vector3d(v / norm) : Eigen::Vector3d::Zero();
}

}  // namespace

v1::Map ToProto(const storage::MapInfo& info) {
  v1::Map map;
  map.set_name(info.name);
  map.set_description(info.description);
  map.set_crs(info.crs);
  map.set_version(info.version);
  map.set_tree_count(info.tree_count);
  if (info.extent) *map.mutable_extent() = ToProto(*info.extent);
  map.set_created_unix_ms(info.created_unix_ms);
  map.set_updated_unix_ms(info.updated_unix_ms);
  return map;
}

v1::Tree ToProto(const storage::TreeRecord& tree) {
  v1::Tree out;
  if (tree.id) out.set_id(*tree.id);
  out.set_x(tree.x);
  out.set_y(tree.y);
  if (tree.z) out.set_z(*tree.z);
  if (tree.dbh) out.set_dbh(*tree.dbh);
  out.mutable_attributes()->insert(tree.attributes.begin(), tree.attributes.end());
  return out;
}

storage::TreeRecord FromProto(const v1::Tree& tree) {
  storage::TreeRecord out;
  if (tree.has_id()) out.id = tree.id();
  out.x = tree.x();
  out.y = tree.y();
  if (tree.has_z()) out.z = tree.z();
  if (tree.has_dbh()) out.dbh = tree.dbh();
  out.attributes.insert(tree.attributes().begin(), tree.attributes().end());
  return out;
}

v1::Box2 ToProto(const storage::Extent& extent) {
  v1::Box2 box;
  box.set_min_x(extent.min_x);
  box.set_min_y(extent.min_y);
  box.set_max_x(extent.max_x);
  box.set_max_y(extent.max_y);
  return box;
}

storage::Extent FromProto(const v1::Box2& box) {
  return storage::Extent{box.min_x(), box.min_y(), box.max_x(), box.max_y()};
}

algorithms::MapTree ToMapTree(const storage::TreeRecord& tree) {
  algorithms::MapTree out;
  out.id = tree.id.value_or(0);
  out.position = Eigen::Vector3d(tree.x, tree.y, tree.z.value_or(algorithms::kUnknown));
  out.dbh = tree.dbh.value_or(algorithms::kUnknown);
  return out;
}

std::vector<algorithms::MapTree> ToMapTrees(const std::vector<storage::TreeRecord>& trees) {
  std::vector<algorithms::MapTree> out;
  out.reserve(trees.size());
  for (const storage::TreeRecord& tree : trees) out.push_back(ToMapTree(tree));
  return out;
}

algorithms::DetectedTree FromProto(const v1::DetectedTree& tree) {
  algorithms::DetectedTree out;
  out.position = FromProto(tree.position());
  out.dbh = tree.has_dbh() ? tree.dbh() : algorithms::kUnknown;
  out.axis = tree.has_axis() ? Direction(FromProto(tree.axis())) : Eigen::Vector3d::Zero();
  out.score = tree.has_score() ? tree.score() : algorithms::kUnknown;
  return out;
}

algorithms::PriorPose FromProto(const v1::PriorPose& prior) {
  algorithms::PriorPose out;
  out.map_from_sensor = FromProto(prior.map_from_sensor());
  out.radius = prior.radius_m();
  return out;
}

algorithms::RelocalizeQuery FromProto(const v1::RelocalizeRequest& request) {
  algorithms::RelocalizeQuery query;
  query.trees.reserve(request.trees_size());
  for (const v1::DetectedTree& tree : request.trees()) query.trees.push_back(FromProto(tree));
  if (request.has_gravity()) query.gravity = Direction(FromProto(request.gravity()));
  if (request.has_prior()) query.prior = FromProto(request.prior());
  return query;
}

v1::RelocalizeResponse::Status ToProto(algorithms::RelocalizeStatus status) {
  switch (status) {
    case algorithms::RelocalizeStatus::kLocalized:
      return v1::RelocalizeResponse::LOCALIZED;
    case algorithms::RelocalizeStatus::kAmbiguous:
      return v1::RelocalizeResponse::AMBIGUOUS;
    case algorithms::RelocalizeStatus::kNotFound:
      return v1::RelocalizeResponse::NOT_FOUND;
  }
  return v1::RelocalizeResponse::STATUS_UNSPECIFIED;
}

v1::RelocalizeResponse ToProto(const algorithms::RelocalizeResult& result) {
  v1::RelocalizeResponse out;
  out.set_status(ToProto(result.status));
  if (result.status == algorithms::RelocalizeStatus::kLocalized) {
    *out.mutable_map_from_sensor() = ToProto(result.map_from_sensor);
  }
  out.set_inliers(result.inliers);
  out.mutable_matches()->Reserve(static_cast<int>(result.matches.size()));
  for (const algorithms::TreeMatch& match : result.matches) {
    v1::TreeMatch* m = out.add_matches();
    m->set_query_index(match.query_index);
    m->set_map_tree_id(match.map_tree_id);
    m->set_distance_m(match.distance);
  }
  out.set_rmse_m(result.rmse);
  out.set_confidence(result.confidence);
  out.set_detail(result.detail);
  return out;
}

}  // namespace forestmap::server
