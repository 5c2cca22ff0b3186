#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include "algorithms/mapping/map_builder_internal.h"
#include "algorithms/relocalization/map_index.h"
#include "algorithms/relocalization/relocalizer.h"

namespace forestmap::algorithms {

Pose4 MapBuilder::Impl::Predict(const BuilderFrame& input, const StoredFrame& previous) {
  Pose4 relative = velocity_;
  double sigma_xy = options_.velocity_sigma_xy, sigma_yaw = options_.velocity_sigma_yaw;
  if (input.odometry) {
    // previous_level_from_level = L_prev * previous_sensor_from_sensor * L^-1 (this frame's
    // levelling is not known before Prepare, so the odometry's own tilt is used).
    Pose3 prev_level = Pose3::Identity();
    prev_level.linear() = previous.level_from_sensor;
    const Pose3 moved = prev_level * *input.odometry * prev_level.inverse();
    relative = ToPose4(moved);
    sigma_xy = options_.odometry_sigma_xy;
    sigma_yaw = options_.odometry_sigma_yaw;
  }
  // After failed frames the prediction has moved on with the last motion.
  ekf_.Predict(relative, sigma_xy, sigma_yaw);
  return ekf_.Pose(previous.pose.translation.z() + relative.translation.z());
}

MapBuilder::Impl::Fix MapBuilder::Impl::FromIcp(const TreeIcpResult& icp, const StoredFrame& frame,
                                                FrameFix how) const {
  Fix fix;
  fix.how = how;
  fix.pose = icp.map_from_level;
  fix.inliers = icp.inliers;
  fix.rmse = icp.rmse;
  fix.matches = icp.matches;
  // min_inlier_fraction 0.4: 0.25 let wrong fixes through on Oxford_Stein.
  const double considered = std::max<size_t>(1, frame.query.size());
  fix.ok = icp.inliers >= options_.min_inliers &&
           icp.inliers >= options_.min_inlier_fraction * considered;
  const double n = std::max(1, icp.inliers);
  fix.sigma_xy = icp.rmse / std::sqrt(n);
  fix.sigma_yaw = icp.rmse / std::sqrt(n) / 10.0;  // ~10 m lever arm of the matched trees
  return fix;
}

MapBuilder::Impl::Fix MapBuilder::Impl::Localize(const StoredFrame& frame, const Pose4& predicted) {
  const LocalMap local = MakeLocalMap(
      map_->TreesNear(predicted.translation.head<2>(),
                      options_.icp_range + options_.max_correction + options_.prior_radius));
  if (local.points.size() >= 3 && failures_ < options_.global_after) {
    const TreeIcpResult icp =
        TreeIcp(frame.query, frame.query_weights, local.points, *local.xy, predicted,
                options_.icp_gates, options_.icp_iterations, options_.yaw_search, local.variances);
    Fix fix = FromIcp(icp, frame, FrameFix::kTracked);
    const double moved = (icp.map_from_level.translation - predicted.translation).head<2>().norm();
    if (fix.ok && moved <= options_.max_correction) return fix;
  }
  const bool global = failures_ >= options_.global_after;
  std::vector<MapTree> trees;
  if (global) {
    trees = map_->ConfirmedMapTrees();
  } else {
    for (size_t i = 0; i < local.points.size(); ++i) {
      trees.push_back(MapTree{local.ids[i], local.points[i], kUnknown});
    }
  }
  return Search(frame, trees, global ? std::nullopt : std::optional<Pose4>(predicted),
                options_.prior_radius, global ? FrameFix::kGlobal : FrameFix::kRelocalized);
}

MapBuilder::Impl::Fix MapBuilder::Impl::Search(const StoredFrame& frame, std::vector<MapTree> trees,
                                               const std::optional<Pose4>& prior, double radius,
                                               FrameFix how) const {
  Fix none;
  if (trees.size() < 10) return none;
  const LocalMap local = [&] {
    std::vector<TreeEstimate> as_estimates(trees.size());
    for (size_t i = 0; i < trees.size(); ++i) {
      as_estimates[i].id = trees[i].id;
      as_estimates[i].position = trees[i].position;
    }
    return MakeLocalMap(as_estimates);
  }();
  const MapIndex index(std::move(trees), options_.search_index);
  RelocalizeQuery query;
  query.trees = frame.level_trees;
  query.gravity = Eigen::Vector3d(0, 0, -1);  // already levelled
  if (prior) query.prior = PriorPose{ToPose3(*prior), radius};
  const RelocalizeResult answer = Relocalize(index, query, options_.relocalizer);
  if (answer.status != RelocalizeStatus::kLocalized) return none;
  const std::vector<double> fine(options_.icp_gates.end() - 2, options_.icp_gates.end());
  const TreeIcpResult icp = TreeIcp(frame.query, frame.query_weights, local.points, *local.xy,
                                    ToPose4(answer.map_from_sensor), fine, options_.icp_iterations);
  return FromIcp(icp, frame, how);
}

}  // namespace forestmap::algorithms
