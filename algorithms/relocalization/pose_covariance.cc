#include "algorithms/relocalization/pose_covariance.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace forestmap::algorithms {
namespace {

constexpr double kMinSigma = 0.02;  // m, floor of the per-axis residual sd
// Correlated errors: n matched pairs carry the information of about n / kCorrelation
// independent ones (measured: mean NEES on Wild_V02 and on simulated views, docs/performance.md).
constexpr double kCorrelation = 1.3;
// Systematic error of the map against the world, per axis: this share of the residual sd in
// excess of a single frame's detection noise (kDetectionSigma: a perfect map, as in simulated
// views, leaves only that noise, which is independent from tree to tree; what a real map adds,
// its survey's and drift's error, is shared by neighbouring trees), and its heading error over a
// typical lever arm of the matched trees. Calibrated on Wild_V02 against Wild_V01 with the
// locally refined truth and on simulated views (mean NEES, docs/performance.md).
constexpr double kSystematicShare = 0.2;
constexpr double kDetectionSigma = 0.05;  // m, per axis
constexpr double kLeverArm = 10.0;        // m
constexpr double kTiltSigma = 0.017;      // rad (~1 deg), levelling error of roll and pitch
constexpr double kMinZSigma = 0.02;       // m

double ZVariance(std::vector<double> dz) {
  if (dz.size() < 2) return kUnknownVariance;
  std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
  const double median = dz[dz.size() / 2];
  std::vector<double> deviation;
  for (double v : dz) deviation.push_back(std::abs(v - median));
  std::nth_element(deviation.begin(), deviation.begin() + deviation.size() / 2, deviation.end());
  const double sigma = std::max(kMinZSigma, 1.4826 * deviation[deviation.size() / 2]);
  // The median's variance is pi/2 times the mean's.
  return M_PI / 2 * sigma * sigma / static_cast<double>(dz.size()) * kCorrelation;
}

}  // namespace

Eigen::Matrix<double, 6, 6> PoseCovariance(const PoseCovarianceInput& input) {
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();
  cov(2, 2) = ZVariance(input.dz);
  cov(3, 3) = cov(4, 4) = kTiltSigma * kTiltSigma;
  const size_t n = input.sensor_xy.size();
  if (n < 3) {
    cov(0, 0) = cov(1, 1) = cov(5, 5) = kUnknownVariance;
    return cov;
  }
  // Residual of pair i: R(yaw) p_i + t - m_i; Jacobian [I, dR/dyaw p_i] in (x, y, yaw).
  const double c = std::cos(input.yaw), s = std::sin(input.yaw);
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  double sum2 = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& p = input.sensor_xy[i];
    Eigen::Matrix<double, 2, 3> j;
    j << 1, 0, -s * p.x() - c * p.y(), 0, 1, c * p.x() - s * p.y();
    information += j.transpose() * j;
    sum2 += input.residual[i].squaredNorm();
  }
  // Variance from 2n - 3 degrees of freedom; a pose judged with an estimated variance errs like
  // Student's t: its expected normalised error grows by dof / (dof - 2) (8 pairs: 1.18).
  const double dof = 2.0 * n - 3.0;
  const double small_set = dof > 4 ? dof / (dof - 2) : 2.0;
  const double residual2 = sum2 / dof;
  const double sigma2 = std::max(kMinSigma * kMinSigma, residual2) * small_set;
  Eigen::Matrix3d planar = sigma2 * kCorrelation * information.inverse();
  // What the pairs cannot see: the map's local error against the world (survey drift), which
  // grows with how badly the two disagree beyond the detection noise.
  const double systematic2 = kSystematicShare * kSystematicShare *
                             std::max(0.0, residual2 - kDetectionSigma * kDetectionSigma);
  planar(0, 0) += systematic2;
  planar(1, 1) += systematic2;
  planar(2, 2) += systematic2 / (kLeverArm * kLeverArm);
  const int index[3] = {0, 1, 5};
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) cov(index[a], index[b]) = planar(a, b);
  }
  return cov;
}

}  // namespace forestmap::algorithms
