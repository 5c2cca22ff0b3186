#pragma once
// Trunk detection: from one LiDAR scan to the list of stems in it, in the sensor frame.
//
// Stages (each its own function, each with its options):
//   FilterScan      scan_filter.h     valid returns, drone body and origin duplicates removed
//   SegmentGround   ground_model.h    pillar ground + height model (heights above ground)
//   ExtractStemLayer, ClusterStems    stem_clustering.h   0.5-3 m layer, 2-D DBSCAN
//   FitStems        stem_model.h      per-slice RANSAC circles, one cylinder per stem, taper
//                                     DBH, ground point, rejection of crowns and shrubs; for an
//                                     organised cloud with the scan grid (MakeScanGrid), whose
//                                     silhouette edges tell occluded stems from whole ones (DBH
//                                     unknown where the scan does not measure it)
// Positions are the tree-ground intersection (Zmeškalová 2023, sec. 5.3), or without
// any ground in the cloud the axis point at the lowest stem point (ground_known false).

#include <cstdint>
#include <span>
#include <vector>

#include "algorithms/core/point_cloud.h"
#include "algorithms/detection/ground_model.h"
#include "algorithms/detection/scan_filter.h"
#include "algorithms/detection/stem_clustering.h"
#include "algorithms/detection/stem_model.h"

namespace forestmap::algorithms {

struct TrunkDetectionOptions {
  ScanFilterOptions filter;
  GroundOptions ground;
  StemLayerOptions layer;
  StemClusterOptions cluster;
  StemModelOptions stem;
  void Check() const;
};

// Per-stage counts and wall times (microseconds), for summaries and benchmarks.
struct TrunkDetectionStats {
  size_t input_points = 0;
  size_t valid_points = 0;  // after FilterScan
  size_t self_returns = 0;  // drone body + origin duplicates
  size_t ground_points = 0;
  int ground_cells = 0;
  size_t stem_layer_points = 0;
  size_t clusters = 0;
  size_t circles = 0;     // accepted slice circles
  size_t candidates = 0;  // linked stems considered
  size_t trees = 0;
  int64_t filter_us = 0;
  int64_t ground_us = 0;
  int64_t layer_us = 0;
  int64_t cluster_us = 0;
  int64_t fit_us = 0;
  int64_t total_us = 0;
};

struct TrunkDetectionResult {
  std::vector<DetectedTrunk> trees;  // best score first
  bool ground_known = false;         // false: positions are the lowest stem points seen
  TrunkDetectionStats stats;
  StemModelStats stem_stats;  // rejection reasons
};

// Throws std::invalid_argument for invalid options; never for the scan's content.
TrunkDetectionResult DetectTrunks(const PointCloud& cloud, const TrunkDetectionOptions& options);

// The organised scan behind FilterScan's points (stem_model.h): every beam's return and each kept
// point's beam (source_index). A view of `cloud` and `source_index`, which must outlive it; empty
// for an unorganised cloud.
ScanGrid MakeScanGrid(const PointCloud& cloud, std::span<const uint32_t> source_index);

// The DetectedTree part of each trunk (for the relocalizer and the CSV writer).
std::vector<DetectedTree> ToDetectedTrees(const std::vector<DetectedTrunk>& trunks);

}  // namespace forestmap::algorithms
