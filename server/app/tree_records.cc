#include "server/app/tree_records.h"

#include <cmath>
#include <optional>

namespace forestmap::server {
namespace {

std::optional<double> Known(double v) {
  return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

}  // namespace

algorithms::MapTree ToMapTree(const storage::TreeRecord& tree) {
  algorithms::MapTree out;
  out.id = tree.id.value_or(0);
  out.position = Eigen::Vector3d(tree.x, tree.y, tree.z.value_or(algorithms::kUnknown));
  out.dbh = tree.dbh.value_or(algorithms::kUnknown);
  return out;
}

algorithms::TreeObservation ToTreeObservation(const storage::ObservationRecord& record) {
  algorithms::TreeObservation out;
  out.tree_id = record.tree_id;
  out.source = record.source;
  out.frame_id = record.frame_id;
  out.detection_index = record.detection_index;
  out.position = Eigen::Vector3d(record.x, record.y, record.z.value_or(algorithms::kUnknown));
  out.dbh = record.dbh.value_or(algorithms::kUnknown);
  out.weight_xy = record.weight_xy;
  out.weight_dbh = record.weight_dbh;
  out.sensor_position = Eigen::Vector3d(record.sensor_x, record.sensor_y, record.sensor_z);
  out.prior = record.prior;
  return out;
}

storage::ObservationRecord ToObservationRecord(const algorithms::TreeObservation& observation) {
  storage::ObservationRecord out;
  out.tree_id = observation.tree_id;
  out.source = observation.source;
  out.frame_id = observation.frame_id;
  out.detection_index = observation.detection_index;
  out.x = observation.position.x();
  out.y = observation.position.y();
  out.z = Known(observation.position.z());
  out.dbh = Known(observation.dbh);
  out.weight_xy = observation.weight_xy;
  out.weight_dbh = observation.weight_dbh;
  out.sensor_x = observation.sensor_position.x();
  out.sensor_y = observation.sensor_position.y();
  out.sensor_z = observation.sensor_position.z();
  out.prior = observation.prior;
  return out;
}

storage::TreeRecord ToTreeRecord(const algorithms::TreeEstimate& tree,
                                 const std::map<std::string, std::string>& attributes,
                                 const std::set<std::string>& null_attributes) {
  storage::TreeRecord out;
  out.id = tree.id;
  out.x = tree.position.x();
  out.y = tree.position.y();
  out.z = Known(tree.position.z());
  out.dbh = Known(tree.dbh);
  out.attributes = attributes;
  out.null_attributes = null_attributes;
  out.status = tree.status == algorithms::TreeStatus::kConfirmed ? storage::TreeStatus::kConfirmed
                                                                 : storage::TreeStatus::kCandidate;
  out.observations = tree.observations;
  out.position_sigma = Known(tree.position_sigma);
  out.dbh_sigma = Known(tree.dbh_sigma);
  return out;
}

std::vector<algorithms::Polygon> ToPolygons(const storage::Boundary& boundary) {
  const auto ring_of = [](const storage::BoundaryRing& ring) {
    algorithms::Ring points;
    points.reserve(ring.size());
    for (const storage::BoundaryPoint& p : ring) points.emplace_back(p.x, p.y);
    return points;
  };
  std::vector<algorithms::Polygon> polygons;
  polygons.reserve(boundary.size());
  for (const storage::BoundaryPolygon& polygon : boundary) {
    algorithms::Polygon& out = polygons.emplace_back();
    out.outer = ring_of(polygon.outer);
    for (const storage::BoundaryRing& hole : polygon.holes) out.holes.push_back(ring_of(hole));
  }
  return polygons;
}

}  // namespace forestmap::server
