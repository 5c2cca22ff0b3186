#include "algorithms/relocalization/tilt_refinement.h"

#include <Eigen/Cholesky>
#include <stdexcept>

namespace forestmap::algorithms {

void TiltRefinementOptions::Check() const {
  if (min_points < 3 || !(min_spread > 0) || !(huber_scale > 0) || iterations < 1 ||
      !(max_correction > min_correction) || min_correction < 0) {
    throw std::invalid_argument("TiltRefinementOptions: invalid values");
  }
}

std::optional<Eigen::Matrix3d> RefineTilt(const std::vector<Eigen::Vector3d>& levelled,
                                          const std::vector<double>& map_z,
                                          const TiltRefinementOptions& options) {
  options.Check();
  if (levelled.size() != map_z.size() || static_cast<int>(levelled.size()) < options.min_points) {
    return std::nullopt;
  }
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : levelled) mean += p.head<2>() / static_cast<double>(levelled.size());
  double spread2 = 0;
  for (const auto& p : levelled) spread2 += (p.head<2>() - mean).squaredNorm() / levelled.size();
  if (spread2 < options.min_spread * options.min_spread) return std::nullopt;

  // residual_i = map_z_i - z_i = c + a (x_i - mean_x) + b (y_i - mean_y), Huber IRLS.
  Eigen::Vector3d params = Eigen::Vector3d::Zero();
  std::vector<double> weights(levelled.size(), 1.0);
  for (int it = 0; it < options.iterations; ++it) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < levelled.size(); ++i) {
      const Eigen::Vector3d row(1.0, levelled[i].x() - mean.x(), levelled[i].y() - mean.y());
      ata += weights[i] * row * row.transpose();
      atb += weights[i] * row * (map_z[i] - levelled[i].z());
    }
    params = ata.ldlt().solve(atb);
    for (size_t i = 0; i < levelled.size(); ++i) {
      const Eigen::Vector3d row(1.0, levelled[i].x() - mean.x(), levelled[i].y() - mean.y());
      const double r = std::abs(map_z[i] - levelled[i].z() - row.dot(params));
      weights[i] = r <= options.huber_scale ? 1.0 : options.huber_scale / r;
    }
  }
  if (!params.allFinite()) return std::nullopt;
  // Heights should rise by a per metre of x and b per metre of y: rotate about y by -a and
  // about x by +b (small angles).
  const double about_y = -std::atan(params.y()), about_x = std::atan(params.z());
  const double angle = std::hypot(about_x, about_y);
  if (angle < options.min_correction || angle > options.max_correction) return std::nullopt;
  return (Eigen::AngleAxisd(about_x, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(about_y, Eigen::Vector3d::UnitY()))
      .toRotationMatrix();
}

}  // namespace forestmap::algorithms
