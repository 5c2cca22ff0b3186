#include "algorithms/mapping/tree_icp.h"

#include <algorithm>
#include <unordered_map>

namespace forestmap::algorithms {

Pose3 ToPose3(const Pose4& pose) {
  return PoseFromXyzYaw(pose.translation.x(), pose.translation.y(), pose.translation.z(), pose.yaw);
}

Pose4 ToPose4(const Pose3& pose) {
  Pose4 out;
  out.translation = pose.translation();
  out.yaw = YawOf(pose.linear());
  return out;
}

namespace {

constexpr double kHeightRange = 15.0;  // m, query trees that measure the height offset

// Associates query trees (moved by `pose`) with their nearest map tree within `gate`; a map tree
// keeps only its closest query tree.
std::vector<std::pair<int, int>> Associate(const std::vector<Eigen::Vector3d>& query,
                                           const KdTree<double, 2>& map_xy, const Pose4& pose,
                                           double gate) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  std::unordered_map<int, std::pair<int, double>> best;  // map index -> (query, d2)
  for (size_t q = 0; q < query.size(); ++q) {
    const double x = pose.translation.x() + c * query[q].x() - s * query[q].y();
    const double y = pose.translation.y() + s * query[q].x() + c * query[q].y();
    const auto [m, d2] = map_xy.Nearest({x, y});
    if (m < 0 || d2 > gate * gate) continue;
    const auto it = best.find(static_cast<int>(m));
    if (it == best.end() || d2 < it->second.second) {
      best[static_cast<int>(m)] = {static_cast<int>(q), d2};
    }
  }
  std::vector<std::pair<int, int>> matches;
  for (const auto& [m, qd] : best) matches.emplace_back(qd.first, m);
  std::sort(matches.begin(), matches.end());
  return matches;
}

// ICP rounds at one gate: associate, then weighted 2-D Procrustes (yaw from the
// cross-covariance of the centred point sets).
void Refine(const std::vector<Eigen::Vector3d>& query, const std::vector<double>& query_weights,
            const std::vector<Eigen::Vector3d>& map, const std::vector<double>& map_variances,
            const KdTree<double, 2>& map_xy, double gate, int iterations, Pose4& pose) {
  for (int it = 0; it < iterations; ++it) {
    const auto matches = Associate(query, map_xy, pose, gate);
    if (matches.size() < 3) return;
    // Each match weighs by the inverse of its combined variance (detection + map tree).
    std::vector<double> w(matches.size());
    double w_sum = 0;
    Eigen::Vector2d q_mean = Eigen::Vector2d::Zero(), m_mean = Eigen::Vector2d::Zero();
    for (size_t k = 0; k < matches.size(); ++k) {
      const auto [q, m] = matches[k];
      const double map_variance = map_variances.empty() ? 0.0 : map_variances[m];
      w[k] = 1.0 / (1.0 / query_weights[q] + map_variance);
      w_sum += w[k];
      q_mean += w[k] * query[q].head<2>();
      m_mean += w[k] * map[m].head<2>();
    }
    q_mean /= w_sum;
    m_mean /= w_sum;
    double sxx = 0, sxy = 0;
    for (size_t k = 0; k < matches.size(); ++k) {
      const auto [q, m] = matches[k];
      const Eigen::Vector2d a = query[q].head<2>() - q_mean;
      const Eigen::Vector2d b = map[m].head<2>() - m_mean;
      sxx += w[k] * a.dot(b);
      sxy += w[k] * (a.x() * b.y() - a.y() * b.x());
    }
    pose.yaw = std::atan2(sxy, sxx);
    const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
    pose.translation.head<2>() =
        m_mean - Eigen::Vector2d(c * q_mean.x() - s * q_mean.y(), s * q_mean.x() + c * q_mean.y());
  }
}

}  // namespace

TreeIcpResult TreeIcp(const std::vector<Eigen::Vector3d>& query,
                      const std::vector<double>& query_weights,
                      const std::vector<Eigen::Vector3d>& map, const KdTree<double, 2>& map_xy,
                      const Pose4& initial, const std::vector<double>& gates, int iterations,
                      double yaw_search, const std::vector<double>& map_variances) {
  TreeIcpResult result;
  result.map_from_level = initial;
  if (query.empty() || map.empty()) return result;
  // The first gate is tried from 7 headings within yaw_search of the initial one (a carried
  // sensor turns fast; the constant-velocity heading can be 20 deg off); the one explaining most
  // trees wins.
  Pose4 pose = initial;
  size_t best_inliers = 0;
  for (int k = 0; k < 7; ++k) {
    const double yaw_offset = yaw_search / 3.0 * ((k + 1) / 2) * (k % 2 == 0 ? -1 : 1);
    Pose4 start = initial;
    start.yaw = WrapAngle(initial.yaw + yaw_offset);
    if (!gates.empty())
      Refine(query, query_weights, map, map_variances, map_xy, gates.front(), iterations, start);
    const size_t inliers =
        Associate(query, map_xy, start, gates.empty() ? 0.5 : gates.front()).size();
    if (inliers > best_inliers) {
      best_inliers = inliers;
      pose = start;
    }
  }
  for (size_t g = 1; g < gates.size(); ++g) {
    Refine(query, query_weights, map, map_variances, map_xy, gates[g], iterations, pose);
  }
  const double last_gate = gates.empty() ? 0.5 : gates.back();
  result.matches = Associate(query, map_xy, pose, last_gate);
  result.inliers = static_cast<int>(result.matches.size());
  // z: median height offset of the matched trees that have heights.
  std::vector<double> dz;
  double sum2 = 0;
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  for (const auto& [q, m] : result.matches) {
    const Eigen::Vector2d moved =
        pose.translation.head<2>() +
        Eigen::Vector2d(c * query[q].x() - s * query[q].y(), s * query[q].x() + c * query[q].y());
    sum2 += (moved - map[m].head<2>()).squaredNorm();
    // Near trees only: a levelling error of 1 deg moves a tree 30 m away by 0.5 m in height.
    if (std::isfinite(map[m].z()) && std::isfinite(query[q].z()) &&
        query[q].head<2>().norm() <= kHeightRange) {
      dz.push_back(map[m].z() - query[q].z());
    }
  }
  if (!dz.empty()) {
    std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
    pose.translation.z() = dz[dz.size() / 2];
  }
  result.rmse = result.inliers > 0 ? std::sqrt(sum2 / result.inliers) : 0;
  result.map_from_level = pose;
  return result;
}

}  // namespace forestmap::algorithms
