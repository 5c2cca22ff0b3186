#include "algorithms/core/leveling.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <stdexcept>

namespace forestmap::algorithms {
namespace {

// Principal direction of the axes within `max_angle` of `reference` (all axes if none given).
std::optional<Eigen::Vector3d> MeanAxis(const std::vector<DetectedTree>& trees,
                                        const std::optional<Eigen::Vector3d>& reference,
                                        double max_angle, int min_axes, int* used) {
  const double min_cos = std::cos(max_angle);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  *used = 0;
  for (const DetectedTree& tree : trees) {
    if (!tree.HasAxis() || !tree.axis.allFinite()) continue;
    const Eigen::Vector3d a = tree.axis.normalized();
    if (reference && std::abs(a.dot(*reference)) < min_cos) continue;
    const double weight = IsKnown(tree.score) ? 0.2 + std::clamp(tree.score, 0.0, 1.0) : 1.0;
    scatter += weight * a * a.transpose();
    ++*used;
  }
  if (*used < min_axes) return std::nullopt;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  return solver.eigenvectors().col(2);  // eigenvalues ascending
}

// Sign of the up vector: the stems' points lie mostly below the sensor.
Eigen::Vector3d OrientUp(const Eigen::Vector3d& axis, const std::vector<DetectedTree>& trees) {
  std::vector<double> heights;
  heights.reserve(trees.size());
  for (const DetectedTree& tree : trees) heights.push_back(axis.dot(tree.position));
  if (!heights.empty()) {
    auto mid = heights.begin() + heights.size() / 2;
    std::nth_element(heights.begin(), mid, heights.end());
    if (std::abs(*mid) > 0.2) return *mid < 0 ? axis : Eigen::Vector3d(-axis);
  }
  return axis.z() >= 0 ? axis : Eigen::Vector3d(-axis);  // no clear signal: nearest to sensor z
}

}  // namespace

void LevelingOptions::Check() const {
  if (!(axis_inlier_angle > 0 && axis_inlier_angle < M_PI / 2)) {
    throw std::invalid_argument("LevelingOptions: axis_inlier_angle must be in (0, pi/2)");
  }
  if (min_axes < 1) throw std::invalid_argument("LevelingOptions: min_axes must be >= 1");
}

LevelingResult LevelSensor(const std::vector<DetectedTree>& trees,
                           const std::optional<Eigen::Vector3d>& gravity,
                           const LevelingOptions& options) {
  options.Check();
  LevelingResult result;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (gravity && gravity->allFinite() && gravity->norm() > 1e-9) {
    up = -gravity->normalized();
    result.source = LevelSource::kGravity;
  } else {
    int used = 0;
    std::optional<Eigen::Vector3d> axis =
        MeanAxis(trees, std::nullopt, M_PI / 2, options.min_axes, &used);
    // Two robust passes: drop leaning stems and branches mistaken for stems.
    for (int pass = 0; pass < 2 && axis; ++pass) {
      std::optional<Eigen::Vector3d> refined =
          MeanAxis(trees, axis, options.axis_inlier_angle, options.min_axes, &used);
      if (!refined) break;
      axis = refined;
    }
    if (!axis) return result;
    up = OrientUp(*axis, trees);
    result.source = LevelSource::kStemAxes;
    result.axes_used = used;
  }
  result.level_from_sensor =
      Eigen::Quaterniond::FromTwoVectors(up, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return result;
}

}  // namespace forestmap::algorithms
