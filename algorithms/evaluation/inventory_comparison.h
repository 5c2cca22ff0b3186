#pragma once
// Detected trees against a reference inventory (a field survey), as the backpack/TLS papers
// report it: one-to-one links within a distance, completeness (share of reference trees
// linked), commission (share of detections linked to nothing), position and DBH RMSE and bias
// of the links, and omission by reference DBH class. Horizontal (x, y) only; both sets in one
// frame (register first when they are not: RegisterToReference).

#include <optional>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/evaluation/inventory_links.h"
#include "algorithms/relocalization/relocalizer.h"

namespace forestmap::algorithms {

struct InventoryComparisonOptions {
  double link_distance = 0.8;     // m, a detection and a reference tree this near may be linked
  double dbh_class_width = 0.10;  // m, width of the omission-by-DBH classes (from 0)
  void Check() const;             // throws std::invalid_argument
};

struct DbhClassOmission {
  double min_dbh = 0, max_dbh = 0;  // m, [min, max)
  int reference_trees = 0;
  int linked = 0;
  double omission = 0;  // 1 - linked / reference_trees
};

// Figures over nothing (no reference trees, no detections, no links, no DBH pairs) are nullopt,
// not 0: a report must not show "RMSE 0" for "nothing measured".
struct InventoryComparison {
  std::vector<InventoryLink> links;  // LinkBefore order (by increasing distance)
  int detected_trees = 0, reference_trees = 0;
  std::optional<double> completeness;             // linked reference trees / reference trees
  std::optional<double> commission;               // unlinked detections / detections
  std::optional<double> position_rmse;            // m, horizontal, over the links
  std::optional<double> bias_x, bias_y;           // m, mean detected - reference
  int dbh_pairs = 0;                              // links where both DBHs are known
  std::optional<double> dbh_rmse;                 // m
  std::optional<double> dbh_bias;                 // m, mean detected - reference
  std::vector<DbhClassOmission> omission_by_dbh;  // reference trees with a known DBH
  int reference_without_dbh = 0;                  // reference trees of unknown DBH ...
  int reference_without_dbh_linked = 0;           // ... and how many of them are linked
};

// Completeness over a subset of the reference trees (e.g. those a simulation marks visible).
struct SubsetCompleteness {
  int reference_trees = 0;             // in the subset
  int linked = 0;                      // of them
  std::optional<double> completeness;  // linked / reference_trees; nullopt for an empty subset
};
// `in_subset[r]` says whether reference tree r belongs to the subset (one entry per tree).
SubsetCompleteness CompletenessOver(const InventoryComparison& comparison,
                                    const std::vector<bool>& in_subset);

// Links greedily by increasing distance (each tree at most once, LinkOneToOne): the one-to-one
// assignment the papers use, which equals the optimal one whenever trees are farther apart than
// twice link_distance. O(n log n) in the number of trees.
InventoryComparison CompareInventories(const std::vector<DetectedTree>& detected,
                                       const std::vector<MapTree>& reference,
                                       const InventoryComparisonOptions& options = {});

struct Registration {
  RelocalizeResult result;  // the relocalizer's answer (status, inliers, detail)
  Pose3 reference_from_detected = Pose3::Identity();  // meaningful when localized
};

// Finds the detections in the reference with the relocalizer (global search, no prior), so that
// two surveys in different frames can be compared. Both sets are centred first (projected
// coordinates are large numbers).
Registration RegisterToReference(const std::vector<DetectedTree>& detected,
                                 const std::vector<MapTree>& reference,
                                 const RelocalizerOptions& options = {});

}  // namespace forestmap::algorithms
