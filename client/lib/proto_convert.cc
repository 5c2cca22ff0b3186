#include "client/lib/proto_convert.h"

namespace forestmap::client {

v1::Tree ToProto(const MapTreeRow& row) {
  v1::Tree tree;
  if (row.id) tree.set_id(*row.id);
  tree.set_x(row.x);
  tree.set_y(row.y);
  if (row.z) tree.set_z(*row.z);
  if (row.dbh) tree.set_dbh(*row.dbh);
  tree.mutable_attributes()->insert(row.attributes.begin(), row.attributes.end());
  for (const std::string& name : row.null_attributes) tree.add_null_attributes(name);
  return tree;
}

MapTreeRow FromProto(const v1::Tree& tree) {
  MapTreeRow row;
  if (tree.has_id()) row.id = tree.id();
  row.x = tree.x();
  row.y = tree.y();
  if (tree.has_z()) row.z = tree.z();
  if (tree.has_dbh()) row.dbh = tree.dbh();
  row.attributes.insert(tree.attributes().begin(), tree.attributes().end());
  row.null_attributes.insert(tree.null_attributes().begin(), tree.null_attributes().end());
  return row;
}

v1::DetectedTree ToProto(const algorithms::DetectedTree& tree) {
  v1::DetectedTree out;
  *out.mutable_position() = ToProto(tree.position);
  if (algorithms::IsKnown(tree.dbh)) out.set_dbh(tree.dbh);
  if (tree.HasAxis()) *out.mutable_axis() = ToProto(tree.axis);
  if (algorithms::IsKnown(tree.score)) out.set_score(tree.score);
  return out;
}

v1::SurveyBoundary ToProto(const std::vector<algorithms::Polygon>& polygons) {
  const auto fill = [](const algorithms::Ring& ring, v1::Ring& out) {
    out.mutable_vertices()->Reserve(static_cast<int>(ring.size()));
    for (const Eigen::Vector2d& p : ring) {
      v1::Vector2* vertex = out.add_vertices();
      vertex->set_x(p.x());
      vertex->set_y(p.y());
    }
  };
  v1::SurveyBoundary boundary;
  for (const algorithms::Polygon& polygon : polygons) {
    v1::Polygon* added = boundary.add_polygons();
    fill(polygon.outer, *added->mutable_outer());
    for (const algorithms::Ring& hole : polygon.holes) fill(hole, *added->add_holes());
  }
  return boundary;
}

std::vector<algorithms::Polygon> FromProto(const v1::SurveyBoundary& boundary) {
  const auto ring_of = [](const v1::Ring& ring) {
    algorithms::Ring points;
    points.reserve(static_cast<size_t>(ring.vertices_size()));
    for (const v1::Vector2& p : ring.vertices()) points.emplace_back(p.x(), p.y());
    return points;
  };
  std::vector<algorithms::Polygon> polygons;
  for (const v1::Polygon& polygon : boundary.polygons()) {
    algorithms::Polygon& added = polygons.emplace_back();
    added.outer = ring_of(polygon.outer());
    for (const v1::Ring& hole : polygon.holes()) added.holes.push_back(ring_of(hole));
  }
  return polygons;
}

TreeState StateOf(const v1::Tree& tree) {
  TreeState state;
  state.confirmed = tree.status() != v1::TREE_STATUS_CANDIDATE;
  state.observations = tree.observations();
  if (tree.has_position_sigma_m()) state.position_sigma_m = tree.position_sigma_m();
  if (tree.has_dbh_sigma_m()) state.dbh_sigma_m = tree.dbh_sigma_m();
  if (tree.has_last_seen_unix_ms()) state.last_seen_unix_ms = tree.last_seen_unix_ms();
  return state;
}

}  // namespace forestmap::client
