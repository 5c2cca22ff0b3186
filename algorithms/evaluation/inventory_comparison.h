#pragma once
// Detected trees against a reference inventory (a field survey), as the backpack/TLS papers
// report it: one-to-one links within a distance, completeness (share of reference trees
// linked), commission (share of detections linked to nothing), position and DBH RMSE and bias
// of the links, and omission by reference DBH class. Horizontal (x, y) only; both sets in one
// frame (register first when they are not: RegisterToReference).

#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/relocalization/relocalizer.h"

namespace forestmap::algorithms {

struct InventoryComparisonOptions {
  double link_distance = 0.8;     // m, a detection and a reference tree this near may be linked
  double dbh_class_width = 0.10;  // m, width of the omission-by-DBH classes (from 0)
  void Check() const;             // throws std::invalid_argument
};

struct InventoryLink {
  int detected = 0;     // index into the detections
  int reference = 0;    // index into the reference trees
  double distance = 0;  // m, horizontal
};

struct DbhClassOmission {
  double min_dbh = 0, max_dbh = 0;  // m, [min, max)
  int reference_trees = 0;
  int linked = 0;
  double omission = 0;  // 1 - linked / reference_trees
};

struct InventoryComparison {
  std::vector<InventoryLink> links;  // by increasing distance
  int detected_trees = 0, reference_trees = 0;
  double completeness = 0;                        // linked reference trees / reference trees
  double commission = 0;                          // unlinked detections / detections
  double position_rmse = 0;                       // m, horizontal, over the links
  double bias_x = 0, bias_y = 0;                  // m, mean detected - reference
  int dbh_pairs = 0;                              // links where both DBHs are known
  double dbh_rmse = 0;                            // m
  double dbh_bias = 0;                            // m, mean detected - reference
  std::vector<DbhClassOmission> omission_by_dbh;  // reference trees with a known DBH
  int reference_without_dbh = 0;
};

// Links greedily by increasing distance (each tree at most once): the one-to-one assignment the
// papers use, which equals the optimal one whenever trees are farther apart than twice
// link_distance.
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
