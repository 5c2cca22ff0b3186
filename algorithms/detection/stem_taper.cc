// Diameter at a height along the stem from (height, diameter, weight) samples (stem_model.h):
// the cubic taper of Holmgren et al. eq. 1, d(h) = p1 h^3 + p2 h^2 + p3 h + p4, lowered to a
// smaller degree when the samples span too little of the stem to carry a cubic.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "algorithms/detection/stem_model.h"

namespace forestmap::algorithms {

TaperFit FitTaper(std::span<const TaperSample> samples, double height) {
  TaperFit fit;
  if (samples.empty()) return fit;
  double lo = std::numeric_limits<double>::max(), hi = -lo, d_lo = lo, d_hi = -lo;
  for (const TaperSample& s : samples) {
    lo = std::min(lo, s.height);
    hi = std::max(hi, s.height);
    d_lo = std::min(d_lo, s.diameter);
    d_hi = std::max(d_hi, s.diameter);
  }
  const double span = hi - lo;
  const int n = static_cast<int>(samples.size());
  int degree = n >= 6 && span >= 1.2   ? 3
               : n >= 5 && span >= 1.0 ? 2
               : n >= 3 && span >= 0.5 ? 1
                                       : 0;
  // A polynomial only interpolates: far outside the slices seen keep it linear or constant.
  const double outside = std::max(lo - height, height - hi);
  if (outside > 0.3) degree = std::min(degree, 1);
  if (outside > 1.0) degree = 0;
  fit.degree = degree;
  // Weighted least squares in a centred, scaled height; Huber IRLS against outlier slices.
  const double centre = 0.5 * (lo + hi), scale = std::max(0.5 * span, 0.1);
  std::vector<double> robust(n, 1.0);
  Eigen::VectorXd coeffs = Eigen::VectorXd::Zero(degree + 1);
  for (int iteration = 0; iteration < 4; ++iteration) {
    Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(degree + 1, degree + 1);
    Eigen::VectorXd atb = Eigen::VectorXd::Zero(degree + 1);
    for (int i = 0; i < n; ++i) {
      Eigen::VectorXd row(degree + 1);
      const double u = (samples[i].height - centre) / scale;
      double power = 1;
      for (int k = 0; k <= degree; ++k, power *= u) row(k) = power;
      const double w = samples[i].weight * robust[i];
      ata.noalias() += w * row * row.transpose();
      atb += w * samples[i].diameter * row;
    }
    ata.diagonal().array() += 1e-9;
    coeffs = ata.ldlt().solve(atb);
    for (int i = 0; i < n; ++i) {
      const double u = (samples[i].height - centre) / scale;
      double value = 0, power = 1;
      for (int k = 0; k <= degree; ++k, power *= u) value += coeffs(k) * power;
      const double r = std::abs(samples[i].diameter - value);
      constexpr double kHuber = 0.01;  // m
      robust[i] = r <= kHuber ? 1.0 : kHuber / r;
    }
  }
  const double u = (height - centre) / scale;
  double value = 0, power = 1;
  for (int k = 0; k <= degree; ++k, power *= u) value += coeffs(k) * power;
  fit.diameter = std::clamp(value, d_lo, d_hi);
  return fit;
}

}  // namespace forestmap::algorithms
