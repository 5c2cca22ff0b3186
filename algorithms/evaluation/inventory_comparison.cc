#include "algorithms/evaluation/inventory_comparison.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "algorithms/evaluation/inventory_links.h"
#include "algorithms/relocalization/map_index.h"

namespace forestmap::algorithms {
namespace {

constexpr double kBoundSlack = 1e-9;  // share of a DBH class: rounding of dbh / width

void OmissionByDbh(const std::vector<MapTree>& reference, const std::vector<InventoryLink>& links,
                   double width, InventoryComparison& out) {
  std::vector<bool> linked(reference.size());
  for (const InventoryLink& link : links) linked[link.reference] = true;
  for (size_t r = 0; r < reference.size(); ++r) {
    const double dbh = reference[r].dbh;
    if (!std::isfinite(dbh)) {
      ++out.reference_without_dbh;
      out.reference_without_dbh_linked += linked[r];
      continue;
    }
    // A DBH on a class bound (0.30 m in classes of 0.1 m) belongs to the class it starts, though
    // 0.30 / 0.1 is 2.9999999999999996 in doubles.
    const size_t k = static_cast<size_t>(std::floor(dbh / width + kBoundSlack));
    while (out.omission_by_dbh.size() <= k) {
      const double min = width * static_cast<double>(out.omission_by_dbh.size());
      out.omission_by_dbh.push_back({min, min + width, 0, 0, 0});
    }
    ++out.omission_by_dbh[k].reference_trees;
    out.omission_by_dbh[k].linked += linked[r];
  }
  std::erase_if(out.omission_by_dbh,
                [](const DbhClassOmission& c) { return c.reference_trees == 0; });
  for (DbhClassOmission& c : out.omission_by_dbh) {
    c.omission = 1.0 - static_cast<double>(c.linked) / c.reference_trees;
  }
}

}  // namespace

void InventoryComparisonOptions::Check() const {
  if (!(link_distance > 0)) throw std::invalid_argument("link_distance must be > 0 m");
  if (!(dbh_class_width > 0)) throw std::invalid_argument("dbh_class_width must be > 0 m");
}

InventoryComparison CompareInventories(const std::vector<DetectedTree>& detected,
                                       const std::vector<MapTree>& reference,
                                       const InventoryComparisonOptions& options) {
  options.Check();
  InventoryComparison out;
  out.detected_trees = static_cast<int>(detected.size());
  out.reference_trees = static_cast<int>(reference.size());
  out.links = LinkOneToOne(detected, reference, options.link_distance);
  const double links = static_cast<double>(out.links.size());
  if (!reference.empty()) out.completeness = links / reference.size();
  if (!detected.empty()) out.commission = 1.0 - links / detected.size();
  Eigen::Vector2d offset_sum = Eigen::Vector2d::Zero();
  double squared = 0, dbh_squared = 0, dbh_sum = 0;
  for (const InventoryLink& link : out.links) {
    const Eigen::Vector2d offset =
        detected[link.detected].position.head<2>() - reference[link.reference].position.head<2>();
    squared += offset.squaredNorm();
    offset_sum += offset;
    const double dbh_error = detected[link.detected].dbh - reference[link.reference].dbh;
    if (std::isfinite(dbh_error)) {
      ++out.dbh_pairs;
      dbh_squared += dbh_error * dbh_error;
      dbh_sum += dbh_error;
    }
  }
  if (!out.links.empty()) {
    out.position_rmse = std::sqrt(squared / links);
    out.bias_x = offset_sum.x() / links;
    out.bias_y = offset_sum.y() / links;
  }
  if (out.dbh_pairs > 0) {
    out.dbh_rmse = std::sqrt(dbh_squared / out.dbh_pairs);
    out.dbh_bias = dbh_sum / out.dbh_pairs;
  }
  OmissionByDbh(reference, out.links, options.dbh_class_width, out);
  return out;
}

SubsetCompleteness CompletenessOver(const InventoryComparison& comparison,
                                    const std::vector<bool>& in_subset) {
  SubsetCompleteness out;
  for (const bool in : in_subset) out.reference_trees += in;
  for (const InventoryLink& link : comparison.links) {
    const size_t r = static_cast<size_t>(link.reference);
    if (r < in_subset.size() && in_subset[r]) ++out.linked;
  }
  if (out.reference_trees > 0) {
    out.completeness = static_cast<double>(out.linked) / out.reference_trees;
  }
  return out;
}

Registration RegisterToReference(const std::vector<DetectedTree>& detected,
                                 const std::vector<MapTree>& reference,
                                 const RelocalizerOptions& options) {
  Registration registration;
  if (detected.empty() || reference.empty()) {
    registration.result.detail = "no trees to register";
    return registration;
  }
  // Horizontal centroids; heights are dropped (a survey's z and a scan's are not comparable).
  Eigen::Vector3d detected_centre = Eigen::Vector3d::Zero(),
                  reference_centre = Eigen::Vector3d::Zero();
  for (const DetectedTree& tree : detected) detected_centre.head<2>() += tree.position.head<2>();
  for (const MapTree& tree : reference) reference_centre.head<2>() += tree.position.head<2>();
  detected_centre /= static_cast<double>(detected.size());
  reference_centre /= static_cast<double>(reference.size());
  std::vector<MapTree> centred_reference = reference;
  for (MapTree& tree : centred_reference) {
    tree.position = Eigen::Vector3d(tree.position.x() - reference_centre.x(),
                                    tree.position.y() - reference_centre.y(), kUnknown);
  }
  RelocalizeQuery query;
  for (DetectedTree tree : detected) {
    tree.position = Eigen::Vector3d(tree.position.x() - detected_centre.x(),
                                    tree.position.y() - detected_centre.y(), 0.0);
    tree.axis = Eigen::Vector3d::Zero();
    query.trees.push_back(tree);
  }
  const MapIndex index(std::move(centred_reference));
  registration.result = Relocalize(index, query, options);
  Pose3 to_reference = Pose3::Identity(), from_detected = Pose3::Identity();
  to_reference.translation() = reference_centre;
  from_detected.translation() = -detected_centre;
  registration.reference_from_detected =
      to_reference * registration.result.map_from_sensor * from_detected;
  return registration;
}

}  // namespace forestmap::algorithms
