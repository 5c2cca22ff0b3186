// Trunk detection against the scan simulator's exact truth, over drone poses in real stem maps
// (../shared/data/stemmaps): recall of visible trunks (DBH >= 10 cm, within 20 m), precision,
// position and DBH RMSE (with the share of found trunks that carry a DBH: the detector leaves it
// unknown where the scan does not measure it). 20 poses by default; the full evaluation runs with
//   FORESTMAP_DETECT_POSES=120 ./trunk_detection_sim_test
// and prints the summary (also per scanner).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <set>

#include "algorithms/detection/trunk_detection.h"
#include "algorithms/simulation/scan_simulation.h"
#include "client/io/tree_csv.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

const std::string kStemMaps = std::string(FORESTMAP_SHARED_DATA) + "/stemmaps/";
// Real surveyed maps with DBH and a plot of at least 50 x 38 m.
const char* const kMaps[] = {"spatstat_spruces",    "siplab_boreasSP", "ads_BPoirier",
                             "lidaRtRee_chablais3", "spatstat_waka",   "siplab_boreasSA"};
const char* const kScanners[] = {"os0-64", "os0-128", "os1-64", "os1-128"};
constexpr double kMinDbh = 0.10;        // m, trunks that count for recall
constexpr double kMaxRange = 20.0;      // m
constexpr double kMatchDistance = 0.5;  // m, detection to true stem (horizontal, at the ground)

struct Tally {
  int targets = 0, found = 0, detections = 0, true_detections = 0;
  double position2 = 0, horizontal2 = 0, dbh2 = 0, dbh_bias = 0;
  int matched = 0;
  int with_dbh = 0;  // matched detections that carry a DBH (the detector may leave it unknown)
  double recall() const { return targets ? static_cast<double>(found) / targets : 1; }
  double precision() const {
    return detections ? static_cast<double>(true_detections) / detections : 1;
  }
  double position_rmse() const { return matched ? std::sqrt(position2 / matched) : 0; }
  double horizontal_rmse() const { return matched ? std::sqrt(horizontal2 / matched) : 0; }
  double dbh_rmse() const { return with_dbh ? std::sqrt(dbh2 / with_dbh) : 0; }
  double dbh_share() const { return matched ? static_cast<double>(with_dbh) / matched : 0; }
  void Add(const Tally& o) {
    targets += o.targets, found += o.found, detections += o.detections;
    true_detections += o.true_detections, position2 += o.position2;
    horizontal2 += o.horizontal2, dbh2 += o.dbh2, dbh_bias += o.dbh_bias, matched += o.matched;
    with_dbh += o.with_dbh;
  }
};

std::ostream& operator<<(std::ostream& out, const Tally& t) {
  return out << "recall " << t.recall() << " (" << t.found << "/" << t.targets << "), precision "
             << t.precision() << " (" << t.true_detections << "/" << t.detections
             << "), position rmse " << t.position_rmse() << " m (horizontal " << t.horizontal_rmse()
             << "), dbh rmse " << t.dbh_rmse() << " m of the " << t.dbh_share() << " with a dbh ("
             << t.with_dbh << "), dbh bias " << (t.with_dbh ? t.dbh_bias / t.with_dbh : 0) << " m";
}

// Scores one scan: detections within kMaxRange against every scene tree (precision) and the
// visible trees of DBH >= kMinDbh within kMaxRange (recall, accuracy).
Tally Score(const ScanSimulationResult& scan, const std::vector<DetectedTrunk>& trunks) {
  Tally tally;
  std::vector<int> owner(trunks.size(), -1);
  for (size_t d = 0; d < trunks.size(); ++d) {
    double best = kMatchDistance;
    for (size_t k = 0; k < scan.trees.size(); ++k) {
      const double dist =
          (trunks[d].tree.position.head<2>() - scan.trees[k].position.head<2>()).norm();
      if (dist < best) {
        best = dist;
        owner[d] = static_cast<int>(k);
      }
    }
    if (trunks[d].range > kMaxRange) continue;
    ++tally.detections;
    tally.true_detections += owner[d] >= 0;
  }
  for (size_t k = 0; k < scan.trees.size(); ++k) {
    const SimulatedTreeTruth& truth = scan.trees[k];
    if (!truth.visible || truth.dbh < kMinDbh || truth.range > kMaxRange) continue;
    ++tally.targets;
    bool found = false;
    for (size_t d = 0; d < trunks.size() && !found; ++d) {
      if (owner[d] != static_cast<int>(k)) continue;
      found = true;
      if (std::getenv("FORESTMAP_DETECT_VERBOSE")) {
        // Surface gap (m) at breast height to the nearest other stem: touching stems merge.
        double gap = 1e9;
        const Eigen::Vector3d breast = truth.position + kBreastHeight * truth.axis;
        for (const SimulatedTreeTruth& other : scan.trees) {
          if (other.index == truth.index) continue;
          const Eigen::Vector3d b = other.position + kBreastHeight * other.axis;
          gap = std::min(gap, (b - breast).head<2>().norm() - 0.5 * (other.dbh + truth.dbh));
        }
        std::cout << "gap " << gap << " ";
        std::cout << "hit  tree " << k << " range " << truth.range << " dbh " << truth.dbh
                  << " det " << trunks[d].tree.dbh << " raw " << trunks[d].raw_dbh << " dz "
                  << trunks[d].tree.position.z() - truth.position.z() << " dxy "
                  << (trunks[d].tree.position - truth.position).head<2>().norm() << " radial "
                  << (trunks[d].tree.position - truth.position)
                         .head<2>()
                         .dot(truth.position.head<2>().normalized())
                  << " slices " << trunks[d].slices << " ground " << trunks[d].ground_known
                  << " points " << trunks[d].points_used << " coverage " << trunks[d].arc_coverage
                  << " rms " << trunks[d].residual << " score " << trunks[d].tree.score
                  << " breast " << truth.breast_points << " silhouette "
                  << trunks[d].silhouette_width << " silhouette_rings "
                  << trunks[d].silhouette_rings << " occluded_rings " << trunks[d].occluded_rings
                  << " true_edges " << trunks[d].true_edges << " columns "
                  << trunks[d].visible_columns << " off_centre " << trunks[d].off_centre
                  << " cylinder_dbh " << trunks[d].cylinder_dbh << " cylinder_height "
                  << trunks[d].cylinder_height << " radius_sd " << trunks[d].radius_sd << " fill "
                  << trunks[d].beam_fill << "\n";
      }
      ++tally.found;
      ++tally.matched;
      const Eigen::Vector3d error = trunks[d].tree.position - truth.position;
      tally.position2 += error.squaredNorm();
      tally.horizontal2 += error.head<2>().squaredNorm();
      if (IsKnown(trunks[d].tree.dbh)) {
        const double dbh_error = trunks[d].tree.dbh - truth.dbh;
        tally.dbh2 += dbh_error * dbh_error;
        tally.dbh_bias += dbh_error;
        ++tally.with_dbh;
      }
    }
    if (!found && std::getenv("FORESTMAP_DETECT_VERBOSE")) {
      std::cout << "miss tree " << k << " range " << truth.range << " dbh " << truth.dbh
                << " breast_points " << truth.breast_points << " at " << truth.position.transpose()
                << "\n";
    }
  }
  if (std::getenv("FORESTMAP_DETECT_VERBOSE")) {
    for (size_t d = 0; d < trunks.size(); ++d) {
      if (owner[d] < 0 && trunks[d].range <= kMaxRange) {
        std::cout << "false at " << trunks[d].tree.position.transpose() << " dbh "
                  << trunks[d].tree.dbh << " slices " << trunks[d].slices << " score "
                  << trunks[d].tree.score << "\n";
      }
    }
  }
  return tally;
}

const char* RejectionName(StemRejection r) {
  static const char* const kNames[] = {"none",     "slices", "tilt",  "residual",
                                       "coverage", "dbh",    "score", "shape"};
  return kNames[static_cast<int>(r)];
}

// FORESTMAP_DETECT_DIAGNOSE: reruns the stages on one scan and prints, per missed target, what
// became of its points (layer points and rings, its cluster, rejected stems near it), and per
// false detection the labels of the layer points around it. key=value lines, for scripts.
void Diagnose(const ScanSimulationResult& scan, TrunkDetectionOptions options,
              const std::vector<DetectedTrunk>& trunks, int pose) {
  options.stem.keep_rejected = true;
  const ScanFilterResult filtered = FilterScan(scan.cloud, options.filter);
  GroundOptions ground_options = options.ground;  // as DetectTrunks sets it
  ground_options.sensor_at_origin = options.stem.sensor_at_origin;
  const GroundSegmentation ground = SegmentGround(filtered.points, ground_options);
  const std::vector<uint32_t> layer =
      ExtractStemLayer(ground.height, ground.ground_known, options.layer);
  const StemClusters clusters = ClusterStems(filtered.points, layer, options.cluster);
  const StemModelResult stems =
      FitStems(filtered.points, ground.height, clusters.clusters, ground.model, options.stem,
               MakeScanGrid(scan.cloud, filtered.source_index));
  std::vector<int> cluster_of(filtered.points.size(), -1);
  for (size_t c = 0; c < clusters.clusters.size(); ++c) {
    for (uint32_t i : clusters.clusters[c]) cluster_of[i] = static_cast<int>(c);
  }
  auto label_of = [&](uint32_t i) { return scan.labels[filtered.source_index[i]]; };
  std::vector<double> ground_errors;
  for (const SimulatedTreeTruth& truth : scan.trees) {
    if (!truth.visible || truth.range > kMaxRange || !ground.ground_known) continue;
    const double g = ground.model.Height(truth.position.x(), truth.position.y());
    ground_errors.push_back(IsKnown(g) ? std::abs(g - truth.position.z()) : 99);
  }
  std::sort(ground_errors.begin(), ground_errors.end());
  if (!ground_errors.empty()) {
    std::cout << "GROUND pose=" << pose << " known=" << ground.ground_known
              << " median=" << ground_errors[ground_errors.size() / 2]
              << " p90=" << ground_errors[ground_errors.size() * 9 / 10]
              << " max=" << ground_errors.back() << " n=" << ground_errors.size() << "\n";
  }
  for (size_t k = 0; k < scan.trees.size(); ++k) {
    const SimulatedTreeTruth& truth = scan.trees[k];
    if (!truth.visible || truth.dbh < kMinDbh || truth.range > kMaxRange) continue;
    bool found = false;
    for (const DetectedTrunk& t : trunks) {
      found |= (t.tree.position.head<2>() - truth.position.head<2>()).norm() < kMatchDistance;
    }
    if (found) continue;
    std::map<int, int> in_cluster;
    std::set<int> rings;
    int layer_points = 0;
    for (uint32_t i : layer) {
      if (label_of(i) != static_cast<int>(k)) continue;
      ++layer_points;
      rings.insert(scan.cloud.ring[filtered.source_index[i]]);
      ++in_cluster[cluster_of[i]];
    }
    int best_cluster = -1, best_count = 0;
    for (const auto& [c, n] : in_cluster) {
      if (c >= 0 && n > best_count) best_cluster = c, best_count = n;
    }
    int cluster_size = 0, cluster_same = 0;
    if (best_cluster >= 0) {
      for (uint32_t i : clusters.clusters[best_cluster]) {
        ++cluster_size;
        cluster_same += label_of(i) == static_cast<int>(k);
      }
    }
    std::string reasons;
    const Eigen::Vector3d breast = truth.position + kBreastHeight * truth.axis;
    for (const RejectedStem& r : stems.rejected) {
      if ((r.trunk.breast_height_point.head<2>() - breast.head<2>()).norm() > 0.5) continue;
      reasons += std::string(RejectionName(r.reason)) + ":" + std::to_string(r.chain_slices) + ":" +
                 std::to_string(r.trunk.tree.dbh).substr(0, 5) + ",";
    }
    std::cout << "MISS pose=" << pose << " range=" << truth.range << " dbh=" << truth.dbh
              << " breast=" << truth.breast_points << " layer=" << layer_points
              << " rings=" << rings.size() << " in_cluster=" << best_count
              << " cluster_size=" << cluster_size << " cluster_same=" << cluster_same
              << " ground_error="
              << ground.model.Height(truth.position.x(), truth.position.y()) - truth.position.z()
              << " rejected=" << (reasons.empty() ? "-" : reasons) << "\n";
  }
  for (const DetectedTrunk& t : trunks) {
    if (t.range > kMaxRange) continue;
    int owner = -1;
    double best = kMatchDistance;
    for (size_t k = 0; k < scan.trees.size(); ++k) {
      const double d = (t.tree.position.head<2>() - scan.trees[k].position.head<2>()).norm();
      if (d < best) best = d, owner = static_cast<int>(k);
    }
    if (owner >= 0 && !(std::abs(t.tree.dbh - scan.trees[owner].dbh) >= 0.2)) continue;
    std::map<int, int> labels;
    for (uint32_t i : layer) {
      const Eigen::Vector2d xy = filtered.points[i].head<2>().cast<double>();
      if ((xy - t.breast_height_point.head<2>()).norm() < 0.5 * t.raw_dbh + 0.05) {
        ++labels[label_of(i) >= 0 ? (label_of(i) == owner ? 0 : 1) : label_of(i)];
      }
    }
    double nearest = 1e9;
    for (const SimulatedTreeTruth& truth : scan.trees) {
      nearest = std::min(nearest, (t.tree.position.head<2>() - truth.position.head<2>()).norm());
    }
    std::cout << (owner >= 0 ? "BADDBH" : "FALSE") << " pose=" << pose << " range=" << t.range
              << " dbh=" << t.tree.dbh << " slices=" << t.slices << " score=" << t.tree.score
              << " points=" << t.points_used << " nearest_tree=" << nearest
              << " ground_known=" << t.ground_known << " rms=" << t.residual
              << " coverage=" << t.arc_coverage << " silhouette=" << t.silhouette_width
              << " radius_sd=" << t.radius_sd << " fill=" << t.beam_fill << " labels=";
    for (const auto& [l, n] : labels) std::cout << l << ":" << n << ",";
    std::cout << "\n";
  }
}

struct Evaluation {
  Tally all;
  std::map<std::string, Tally> by_scanner;
};

Evaluation Evaluate(int poses, const TrunkDetectionOptions& options) {
  Evaluation evaluation;
  std::map<std::string, std::unique_ptr<ForestScene>> scenes;
  std::mt19937 rng(2024);
  for (int pose = 0; pose < poses; ++pose) {
    const std::string name = kMaps[pose % std::size(kMaps)];
    if (!scenes.count(name)) {
      const std::vector<MapTree> map =
          client::ToMapTrees(client::ReadMapTreesCsv(kStemMaps + name + ".csv"));
      SceneOptions scene_options;
      scene_options.seed = 7 + pose;
      scenes[name] = std::make_unique<ForestScene>(map, scene_options);
    }
    const ForestScene& scene = *scenes[name];
    const std::string scanner_name = kScanners[(pose / std::size(kMaps)) % std::size(kScanners)];
    const ScannerModel scanner = ScannerPreset(scanner_name);
    // Anywhere over the plot, at least 10 m inside its edge when it is large enough.
    const Eigen::Vector2d lo = scene.min_corner() + Eigen::Vector2d::Constant(40);
    const Eigen::Vector2d hi = scene.max_corner() - Eigen::Vector2d::Constant(40);
    std::uniform_real_distribution<double> u(0, 1), tilt(-0.05, 0.05), height(2, 15);
    const double x =
        lo.x() < hi.x() ? lo.x() + u(rng) * (hi.x() - lo.x()) : 0.5 * (lo.x() + hi.x());
    const double y =
        lo.y() < hi.y() ? lo.y() + u(rng) * (hi.y() - lo.y()) : 0.5 * (lo.y() + hi.y());
    const Pose3 pose3 =
        DronePose(scene, x, y, height(rng), 2 * M_PI * u(rng), tilt(rng), tilt(rng));
    const ScanSimulationResult scan = SimulateScan(scene, pose3, scanner, ScanNoiseOptions{}, pose);
    const TrunkDetectionResult result = DetectTrunks(scan.cloud, options);
    if (std::getenv("FORESTMAP_DETECT_VERBOSE")) {
      std::cout << "pose " << pose << " scanner " << scanner_name << " map " << name << "\n";
    }
    const Tally tally = Score(scan, result.trees);
    if (std::getenv("FORESTMAP_DETECT_DIAGNOSE")) Diagnose(scan, options, result.trees, pose);
    evaluation.all.Add(tally);
    evaluation.by_scanner[scanner_name].Add(tally);
  }
  return evaluation;
}

int PosesFromEnvironment(int fallback) {
  const char* text = std::getenv("FORESTMAP_DETECT_POSES");
  return text ? std::max(1, std::atoi(text)) : fallback;
}

TEST(TrunkDetectionSimTest, RecallPrecisionAndAccuracyOverDronePoses) {
  if (!std::filesystem::exists(kStemMaps))
    FORESTMAP_SKIP_WITHOUT_DATA() << "no stem maps at " << kStemMaps;
  const int poses = PosesFromEnvironment(20);
  TrunkDetectionOptions options;
  options.stem.beam_divergence = 3.1e-3;  // the simulated Ouster beams
  const Evaluation evaluation = Evaluate(poses, options);
  std::cout << poses << " poses: " << evaluation.all << std::endl;
  for (const auto& [name, tally] : evaluation.by_scanner) {
    std::cout << "  " << name << ": " << tally << std::endl;
  }
  // Regression floors at what the detector reaches today (these 20 poses: recall 0.964,
  // precision 0.979, position rmse 12 cm (horizontal 3.3 cm), DBH rmse 1.43 cm of the 88.4% of
  // the found trunks that carry a DBH; 120 poses: recall 0.963, precision 0.984, position 29 cm
  // (horizontal 4.2 cm), DBH 1.32 cm of the 86.1% with a DBH; poses 120-239, not used to choose
  // the thresholds: DBH 1.50 cm of 87.6%). The detector leaves the DBH unknown where the scan
  // does not measure it (stems hidden at both silhouette edges, seen in a few columns;
  // silhouettes of two touching stems; fits that do not know the radius): the RMSE holds only
  // with that share. Most of what remains is stems that touch or overlap in the stem maps
  // (surface gap < 10 cm): seen as one.
  // The bars are recall 0.95, precision 0.97, position rmse 5 cm and DBH rmse 1.5 cm:
  // the 3-D position rmse is NOT met: an OS1 (+-22.5 deg) high up sees no ground near it, and the
  // ground under a near stem is a plane through the ground seen 20-40 m away (or, where shrub
  // tops pass for ground, wrong by metres).
  const Tally& t = evaluation.all;
  ASSERT_GT(t.targets, 50);
  EXPECT_GE(t.recall(), 0.955);
  EXPECT_GE(t.precision(), 0.965);
  EXPECT_LE(t.position_rmse(), 0.15);
  EXPECT_LE(t.horizontal_rmse(), 0.045);
  EXPECT_LE(t.dbh_rmse(), 0.0155);
  EXPECT_GE(t.dbh_share(), 0.85);
}

}  // namespace
}  // namespace forestmap::algorithms
