#pragma once
// Closed-form weighted least-squares rigid fit in the plane (2-D Kabsch / Umeyama, no scale).

#include <Eigen/Core>
#include <cmath>
#include <vector>

namespace forestmap::algorithms {

struct Rigid2 {
  double yaw = 0;                                         // rad
  Eigen::Vector2d translation = Eigen::Vector2d::Zero();  // m

  Eigen::Vector2d operator()(const Eigen::Vector2d& p) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {c * p.x() - s * p.y() + translation.x(), s * p.x() + c * p.y() + translation.y()};
  }
};

// Accumulates weighted point pairs (source -> target) and solves target = R * source + t.
class Rigid2Accumulator {
 public:
  void Add(const Eigen::Vector2d& source, const Eigen::Vector2d& target, double weight = 1.0) {
    w_ += weight;
    sum_s_ += weight * source;
    sum_t_ += weight * target;
    sxx_ += weight * source.x() * target.x();
    sxy_ += weight * source.x() * target.y();
    syx_ += weight * source.y() * target.x();
    syy_ += weight * source.y() * target.y();
  }
  double weight() const { return w_; }

  Rigid2 Solve() const {
    Rigid2 result;
    if (w_ <= 0) return result;
    const Eigen::Vector2d ms = sum_s_ / w_, mt = sum_t_ / w_;
    // Centred cross-covariance terms.
    const double cxx = sxx_ - w_ * ms.x() * mt.x(), cxy = sxy_ - w_ * ms.x() * mt.y();
    const double cyx = syx_ - w_ * ms.y() * mt.x(), cyy = syy_ - w_ * ms.y() * mt.y();
    result.yaw = std::atan2(cxy - cyx, cxx + cyy);
    const double c = std::cos(result.yaw), s = std::sin(result.yaw);
    result.translation = mt - Eigen::Vector2d(c * ms.x() - s * ms.y(), s * ms.x() + c * ms.y());
    return result;
  }

 private:
  double w_ = 0, sxx_ = 0, sxy_ = 0, syx_ = 0, syy_ = 0;
  Eigen::Vector2d sum_s_ = Eigen::Vector2d::Zero(), sum_t_ = Eigen::Vector2d::Zero();
};

}  // namespace forestmap::algorithms
