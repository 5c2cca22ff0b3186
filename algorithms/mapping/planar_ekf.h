#pragma once
// A small EKF on the planar pose (x, y, yaw) of a levelled sensor in the map frame, as in Park &
// Park 2023, sec. 2.4: prediction by a motion model (odometry, or constant
// velocity with a generous noise), update by a tree-map fix measuring the whole pose.

#include "algorithms/core/geometry.h"
#include "algorithms/mapping/pose_graph.h"

namespace forestmap::algorithms {

// EKF on (x, y, yaw) of the levelled sensor in the map frame (Park & Park 2023: motion
// model prediction, tree-map fix as the measurement).
class PlanarEkf {
 public:
  void Reset(const Pose4& pose, double sigma_xy, double sigma_yaw) {
    x_ = Eigen::Vector3d(pose.translation.x(), pose.translation.y(), pose.yaw);
    p_ = Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy, sigma_yaw * sigma_yaw)
             .asDiagonal();
  }
  // Moves by `relative` (body frame) with the given per-frame noise.
  void Predict(const Pose4& relative, double sigma_xy, double sigma_yaw) {
    const double c = std::cos(x_(2)), s = std::sin(x_(2));
    const Eigen::Vector2d d = relative.translation.head<2>();
    Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
    f(0, 2) = -s * d.x() - c * d.y();
    f(1, 2) = c * d.x() - s * d.y();
    x_(0) += c * d.x() - s * d.y();
    x_(1) += s * d.x() + c * d.y();
    x_(2) = WrapAngle(x_(2) + relative.yaw);
    const Eigen::Matrix3d q =
        Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy, sigma_yaw * sigma_yaw)
            .asDiagonal();
    p_ = f * p_ * f.transpose() + q;
  }
  void Update(const Pose4& measured, double sigma_xy, double sigma_yaw) {
    Eigen::Vector3d innovation(measured.translation.x() - x_(0), measured.translation.y() - x_(1),
                               WrapAngle(measured.yaw - x_(2)));
    const Eigen::Matrix3d r =
        Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy, sigma_yaw * sigma_yaw)
            .asDiagonal();
    const Eigen::Matrix3d k = p_ * (p_ + r).inverse();
    x_ += k * innovation;
    x_(2) = WrapAngle(x_(2));
    p_ = (Eigen::Matrix3d::Identity() - k) * p_;
  }
  Pose4 Pose(double z) const {
    Pose4 out;
    out.translation = Eigen::Vector3d(x_(0), x_(1), z);
    out.yaw = x_(2);
    return out;
  }

 private:
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d p_ = Eigen::Matrix3d::Identity();
};

}  // namespace forestmap::algorithms
