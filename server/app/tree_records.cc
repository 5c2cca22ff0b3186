#include "server/app/tree_records.h"

#include <charconv>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace forestmap::server {
namespace {

std::optional<double> Known(double v) {
  return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

// A summary's statistics as stored: numbers separated by spaces, doubles in their shortest exact
// form (std::to_chars), so that a stored summary reads back bit for bit:
//   "1 rows surveyed" then weight mean m2 count of xy (mean x and y), z and DBH, then the number of
//   view anchors and their x y.
void Put(std::string& out, double v) {
  char buffer[32];
  const auto end = std::to_chars(buffer, buffer + sizeof buffer, v).ptr;
  out.push_back(' ');
  out.append(buffer, end);
}

std::string EncodeSummary(const algorithms::ObservationSummary& s) {
  std::string out = "1";
  for (const double v :
       {double(s.rows), double(s.surveyed), s.xy.weight, s.xy.mean.x(), s.xy.mean.y(), s.xy.m2,
        double(s.xy.count), s.z.weight, s.z.mean, s.z.m2, double(s.z.count), s.dbh.weight,
        s.dbh.mean, s.dbh.m2, double(s.dbh.count), double(s.view_anchors.size())}) {
    Put(out, v);
  }
  for (const Eigen::Vector2d& anchor : s.view_anchors) Put(out, anchor.x()), Put(out, anchor.y());
  return out;
}

std::shared_ptr<const algorithms::ObservationSummary> DecodeSummary(const std::string& text,
                                                                    int64_t row) {
  std::vector<double> v;
  const char* p = text.data();
  const char* end = p + text.size();
  while (p < end) {
    while (p < end && *p == ' ') ++p;
    double value = 0;
    const auto [next, error] = std::from_chars(p, end, value);
    if (error != std::errc() || next == p) break;
    v.push_back(value);
    p = next;
  }
  if (p != end || v.size() < 17 || v[0] != 1 || v.size() != 17 + 2 * size_t(v[16])) {
    throw std::runtime_error("observation row " + std::to_string(row) +
                             ": the stored summary is not one this server reads");
  }
  auto s = std::make_shared<algorithms::ObservationSummary>();
  s->rows = static_cast<int>(v[1]);
  s->surveyed = v[2] != 0;
  s->xy = {v[3], Eigen::Vector2d(v[4], v[5]), v[6], static_cast<int>(v[7])};
  s->z = {v[8], v[9], v[10], static_cast<int>(v[11])};
  s->dbh = {v[12], v[13], v[14], static_cast<int>(v[15])};
  for (size_t k = 17; k + 1 < v.size(); k += 2) s->view_anchors.emplace_back(v[k], v[k + 1]);
  return s;
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
  if (record.summary) out.summary = DecodeSummary(*record.summary, record.id);
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
  if (observation.summary) out.summary = EncodeSummary(*observation.summary);
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
