#include "algorithms/evaluation/map_evaluation.h"

#include <Eigen/Geometry>
#include <stdexcept>
#include <string>

#include "algorithms/core/kdtree.h"
#include "algorithms/evaluation/reloc_evaluation.h"

namespace forestmap::algorithms {
namespace {

std::unique_ptr<KdTree<double, 2>> IndexXy(const std::vector<MapTree>& trees) {
  std::vector<KdTree<double, 2>::Point> points;
  points.reserve(trees.size());
  for (const MapTree& t : trees) points.push_back({t.position.x(), t.position.y()});
  return std::make_unique<KdTree<double, 2>>(std::move(points));
}

}  // namespace

void TreeMapComparisonOptions::Check() const {
  if (!(match_distance > 0)) {
    throw std::invalid_argument("TreeMapComparisonOptions.match_distance must be > 0 m");
  }
  if (!(duplicate_distance >= 0)) {
    throw std::invalid_argument("TreeMapComparisonOptions.duplicate_distance must be >= 0 m");
  }
}

TreeMapComparison CompareTreeMaps(const std::vector<MapTree>& built,
                                  const std::vector<MapTree>& reference,
                                  const TreeMapComparisonOptions& options) {
  options.Check();
  TreeMapComparison out;
  out.reference_trees = static_cast<int>(reference.size());
  out.built_trees = static_cast<int>(built.size());
  if (built.empty() || reference.empty()) return out;
  const auto built_xy = IndexXy(built);
  const auto reference_xy = IndexXy(reference);
  std::vector<double> distances, dbh_diffs;
  for (const MapTree& ref : reference) {
    const auto [b, d2] = built_xy->Nearest({ref.position.x(), ref.position.y()});
    const double d = std::sqrt(d2);
    if (d > options.match_distance) continue;
    ++out.found;
    distances.push_back(d);
    if (IsKnown(ref.dbh) && IsKnown(built[b].dbh)) {
      dbh_diffs.push_back(std::abs(ref.dbh - built[b].dbh));
    }
  }
  out.found_fraction = static_cast<double>(out.found) / out.reference_trees;
  out.distance_p50 = Percentile(distances, 0.5);
  out.distance_p95 = Percentile(distances, 0.95);
  out.dbh_abs_diff_p50 = Percentile(dbh_diffs, 0.5);
  // Nearest reference tree of each built tree (-1 when none within 2 x duplicate_distance).
  std::vector<int64_t> nearest_ref(built.size(), -1);
  for (size_t i = 0; i < built.size(); ++i) {
    const auto [r, d2] = reference_xy->Nearest({built[i].position.x(), built[i].position.y()});
    if (d2 <= options.match_distance * options.match_distance) {
      nearest_ref[i] = r;
    } else {
      ++out.unmatched_built;
    }
  }
  std::vector<std::pair<uint32_t, double>> near;
  for (size_t i = 0; i < built.size(); ++i) {
    built_xy->Radius({built[i].position.x(), built[i].position.y()}, options.duplicate_distance,
                     near);
    for (const auto& [j, d2] : near) {
      if (j <= i) continue;
      ++out.close_pairs;
      // One stem: both explain the same reference tree, or only one explains any.
      if (nearest_ref[i] == nearest_ref[j] || nearest_ref[i] < 0 || nearest_ref[j] < 0) {
        ++out.duplicates;
      }
    }
  }
  return out;
}

TrajectoryError CompareTrajectories(const std::vector<Pose3>& estimate,
                                    const std::vector<Pose3>& truth, Alignment alignment) {
  if (estimate.size() != truth.size()) {
    throw std::invalid_argument("CompareTrajectories: " + std::to_string(estimate.size()) +
                                " estimated poses for " + std::to_string(truth.size()) +
                                " true poses");
  }
  TrajectoryError out;
  out.poses = static_cast<int>(estimate.size());
  if (estimate.empty()) return out;
  Eigen::Matrix3Xd src(3, estimate.size()), dst(3, truth.size());
  for (size_t i = 0; i < estimate.size(); ++i) {
    src.col(i) = estimate[i].translation();
    dst.col(i) = truth[i].translation();
  }
  const bool planar = alignment != Alignment::kRigid;
  if (estimate.size() >= 3 && !planar) {
    out.truth_from_estimate.matrix() = Eigen::umeyama(src, dst, false);
  } else if (estimate.size() >= 3) {
    // 2-D Procrustes: yaw from the cross-covariance of the centred xy sets.
    const Eigen::Vector3d src_mean = src.rowwise().mean(), dst_mean = dst.rowwise().mean();
    double sxx = 0, sxy = 0, spread = 0;
    for (Eigen::Index i = 0; i < src.cols(); ++i) {
      const Eigen::Vector2d a = (src.col(i) - src_mean).head<2>();
      const Eigen::Vector2d b = (dst.col(i) - dst_mean).head<2>();
      sxx += a.dot(b);
      sxy += a.x() * b.y() - a.y() * b.x();
      spread += a.squaredNorm();
    }
    const double yaw = std::atan2(sxy, sxx);
    if (alignment == Alignment::kPlanarSimilarity && spread > 0) {
      out.scale = std::hypot(sxx, sxy) / spread;  // Umeyama's scale in 2-D
    }
    const Eigen::Vector2d t = dst_mean.head<2>() - out.scale *
                                                       Eigen::Rotation2Dd(yaw).toRotationMatrix() *
                                                       src_mean.head<2>();
    out.truth_from_estimate = PoseFromXyzYaw(t.x(), t.y(), dst_mean.z() - src_mean.z(), yaw);
  }
  std::vector<double> errors(estimate.size());
  double sum2 = 0;
  for (size_t i = 0; i < estimate.size(); ++i) {
    const Eigen::Vector3d d = out.ToTruth(src.col(i)) - dst.col(i);
    errors[i] = planar ? d.head<2>().norm() : d.norm();
    sum2 += errors[i] * errors[i];
    out.ate_max = std::max(out.ate_max, errors[i]);
  }
  out.ate_rmse = std::sqrt(sum2 / estimate.size());
  out.ate_p50 = Percentile(errors, 0.5);
  return out;
}

}  // namespace forestmap::algorithms
