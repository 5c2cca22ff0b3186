#include "algorithms/detection/trunk_detection.h"

#include <chrono>
#include <cmath>

namespace forestmap::algorithms {
namespace {

using Clock = std::chrono::steady_clock;

int64_t MicrosSince(Clock::time_point& start) {
  const Clock::time_point now = Clock::now();
  const int64_t us = std::chrono::duration_cast<std::chrono::microseconds>(now - start).count();
  start = now;
  return us;
}

}  // namespace

void TrunkDetectionOptions::Check() const {
  filter.Check();
  ground.Check();
  layer.Check();
  cluster.Check();
  stem.Check();
}

TrunkDetectionResult DetectTrunks(const PointCloud& cloud, const TrunkDetectionOptions& options) {
  options.Check();
  TrunkDetectionResult result;
  TrunkDetectionStats& stats = result.stats;
  const Clock::time_point begin = Clock::now();
  Clock::time_point t = begin;
  stats.input_points = cloud.size();

  const ScanFilterResult filtered = FilterScan(cloud, options.filter);
  stats.valid_points = filtered.points.size();
  stats.self_returns = filtered.self_returns + filtered.origin_duplicates;
  stats.filter_us = MicrosSince(t);

  GroundOptions ground_options = options.ground;
  ground_options.sensor_at_origin =
      ground_options.sensor_at_origin || options.stem.sensor_at_origin;
  const GroundSegmentation ground = SegmentGround(filtered.points, ground_options);
  result.ground_known = ground.ground_known;
  stats.ground_points = ground.ground_points;
  stats.ground_cells = ground.ground_cells;
  stats.ground_us = MicrosSince(t);

  const std::vector<uint32_t> layer =
      ExtractStemLayer(ground.height, ground.ground_known, options.layer);
  stats.stem_layer_points = layer.size();
  stats.layer_us = MicrosSince(t);

  const StemClusters clusters = ClusterStems(filtered.points, layer, options.cluster);
  stats.clusters = clusters.clusters.size();
  stats.cluster_us = MicrosSince(t);

  StemModelOptions stem_options = options.stem;
  if (stem_options.angular_step <= 0 && cloud.IsOrganised()) {
    stem_options.angular_step = 2 * M_PI / cloud.width;  // columns of one revolution
  }
  const ScanGrid grid =
      stem_options.sensor_at_origin ? MakeScanGrid(cloud, filtered.source_index) : ScanGrid{};
  StemModelResult stems =
      FitStems(filtered.points, ground.height, clusters.clusters, ground.model, stem_options, grid);
  result.trees = std::move(stems.trunks);
  result.stem_stats = stems.stats;
  stats.circles = stems.stats.circles;
  stats.candidates = stems.stats.chains;
  stats.trees = result.trees.size();
  stats.fit_us = MicrosSince(t);
  stats.total_us = std::chrono::duration_cast<std::chrono::microseconds>(t - begin).count();
  return result;
}

ScanGrid MakeScanGrid(const PointCloud& cloud, std::span<const uint32_t> source_index) {
  ScanGrid grid;
  if (!cloud.IsOrganised() || cloud.points.size() != size_t{cloud.width} * cloud.height) {
    return grid;
  }
  grid.rings = static_cast<int>(cloud.height);
  grid.columns = static_cast<int>(cloud.width);
  // Every return counts, the drone's own body too: it hides what lies behind it.
  grid.returns = cloud.points;
  grid.beam = source_index;
  // The turning direction from the azimuths of neighbouring returns (the cloud does not say).
  double turn = 0;
  for (size_t i = 0; i + 1 < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    const Eigen::Vector3f& q = cloud.points[i + 1];
    if ((i + 1) % cloud.width == 0 || !p.allFinite() || !q.allFinite()) continue;
    turn += std::remainder(std::atan2(q.y(), q.x()) - std::atan2(p.y(), p.x()), 2 * M_PI);
    if (std::abs(turn) > 1.0) break;
  }
  grid.azimuth_step = (turn < 0 ? -2 : 2) * M_PI / cloud.width;
  return grid;
}

std::vector<DetectedTree> ToDetectedTrees(const std::vector<DetectedTrunk>& trunks) {
  std::vector<DetectedTree> trees;
  trees.reserve(trunks.size());
  for (const DetectedTrunk& trunk : trunks) trees.push_back(trunk.tree);
  return trees;
}

}  // namespace forestmap::algorithms
