#include "algorithms/detection/cylinder_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace forestmap::algorithms {
namespace {

using Params = Eigen::Matrix<double, 5, 1>;  // x0, y0, sx, sy, r

// The axis of a parameter vector, computed once per evaluation over all points.
struct AxisFrame {
  explicit AxisFrame(const Params& q, double z_ref)
      : origin(q(0), q(1), z_ref),
        m_norm(Eigen::Vector3d(q(2), q(3), 1.0).norm()),
        u(Eigen::Vector3d(q(2), q(3), 1.0) / m_norm),
        radius(q(4)) {}
  Eigen::Vector3d origin;
  double m_norm;
  Eigen::Vector3d u;
  double radius;
};

// Residual of p (distance to the axis minus r) and, if `jacobian`, its derivatives.
double Residual(const Eigen::Vector3d& p, const AxisFrame& f, Params* jacobian) {
  const Eigen::Vector3d w = p - f.origin;
  const double t = w.dot(f.u);
  const Eigen::Vector3d v = w - t * f.u;
  const double d = std::max(v.norm(), 1e-12);
  if (jacobian) {
    const Eigen::Vector3d n = v / d;  // n is orthogonal to u
    *jacobian << -n.x(), -n.y(), -t * n.x() / f.m_norm, -t * n.y() / f.m_norm, -1.0;
  }
  return d - f.radius;
}

// Distance of the ray (through the origin) from the axis, minus r, and (if `jacobian`) its
// derivatives: with m = (sx, sy, 1) and the common normal n = m x d of the two lines, the distance
// is |g| / |n|, g = origin . n.
double TangentResidual(const TangentRay& ray, const Params& q, double z_ref, Params* jacobian) {
  const Eigen::Vector3d& d = ray.direction;
  const Eigen::Vector3d origin(q(0), q(1), z_ref);
  const Eigen::Vector3d n = Eigen::Vector3d(q(2), q(3), 1.0).cross(d);
  const double norm = std::max(n.norm(), 1e-12);
  const double g = origin.dot(n);
  if (jacobian) {
    const double sign = g < 0 ? -1.0 : 1.0;
    const Eigen::Vector3d dn_dsx(0, -d.z(), d.y()), dn_dsy(d.z(), 0, -d.x());  // e_x, e_y x d
    auto slope = [&](const Eigen::Vector3d& dn) {
      return sign * origin.dot(dn) / norm - std::abs(g) * n.dot(dn) / (norm * norm * norm);
    };
    *jacobian << sign * n.x() / norm, sign * n.y() / norm, slope(dn_dsx), slope(dn_dsy), -1.0;
  }
  return std::abs(g) / norm - q(4);
}

// IRLS weight of a residual of x standard deviations: Huber (1.5) from a rough seed, else
// Tukey's biweight (4.685), which ignores far outliers entirely.
double RobustWeight(double x, bool huber) {
  if (huber) return x <= 1.5 ? 1.0 : 1.5 / x;
  const double t = x / 4.685;
  return t < 1 ? (1 - t * t) * (1 - t * t) : 0.0;
}

// Tangent rays add w_k e_k^2 with w_k = tangent_weights[k] (noise / sd_k)^2.
struct Tangents {
  std::span<const TangentRay> rays;
  std::vector<double> weights;  // robust weights, one per ray
};

double Cost(std::span<const Eigen::Vector3d> points, const std::vector<double>& weights,
            const Params& q, double z_ref, const RadiusPrior& prior, const Tangents& tangents,
            double noise, Eigen::Matrix<double, 5, 5>* jtj = nullptr, Params* jte = nullptr) {
  if (jtj) jtj->setZero(), jte->setZero();
  double cost = 0;
  Params j;
  const AxisFrame frame(q, z_ref);
  for (size_t i = 0; i < points.size(); ++i) {
    const double e = Residual(points[i], frame, jtj ? &j : nullptr);
    cost += weights[i] * e * e;
    if (jtj) {
      jtj->noalias() += weights[i] * j * j.transpose();
      *jte += weights[i] * e * j;
    }
  }
  for (size_t k = 0; k < tangents.rays.size(); ++k) {
    const double e = TangentResidual(tangents.rays[k], q, z_ref, jtj ? &j : nullptr);
    const double w =
        tangents.weights[k] * (noise / tangents.rays[k].sd) * (noise / tangents.rays[k].sd);
    cost += w * e * e;
    if (jtj) {
      jtj->noalias() += w * j * j.transpose();
      *jte += w * e * j;
    }
  }
  if (prior.radius > 0) {
    // One pseudo-observation of r with sd_below or sd_above, in units of the point noise.
    const double e = q(4) - prior.radius;
    const double sd = e < 0 ? prior.sd_below : prior.sd_above;
    const double w = (noise / sd) * (noise / sd);
    cost += w * e * e;
    if (jtj) {
      (*jtj)(4, 4) += w;
      (*jte)(4) += w * e;
    }
  }
  return cost;
}

// Levenberg-Marquardt on the weighted squared residuals, from q. Each candidate's normal
// equations come with its cost (one pass over the points per step), ready for the next step.
Params Minimise(std::span<const Eigen::Vector3d> points, const std::vector<double>& weights,
                Params q, double z_ref, const RadiusPrior& prior, const Tangents& tangents,
                double noise, int max_iterations) {
  Eigen::Matrix<double, 5, 5> jtj, next_jtj;
  Params jte, next_jte;
  double cost = Cost(points, weights, q, z_ref, prior, tangents, noise, &jtj, &jte);
  double lambda = 1e-3;
  for (int it = 0, tries = 0; it < max_iterations && tries < 8;) {
    Eigen::Matrix<double, 5, 5> damped = jtj;
    damped.diagonal() *= 1.0 + lambda;
    damped.diagonal().array() += 1e-12;
    const Params step = damped.ldlt().solve(-jte);
    const Params next = q + step;
    const double next_cost = next(4) > 0 ? Cost(points, weights, next, z_ref, prior, tangents,
                                                noise, &next_jtj, &next_jte)
                                         : std::numeric_limits<double>::max();
    if (next_cost < cost) {
      const double gain = cost - next_cost;
      q = next;
      cost = next_cost;
      jtj = next_jtj;
      jte = next_jte;
      lambda = std::max(lambda * 0.1, 1e-9);
      if (gain < 1e-6 * cost || step.norm() < 1e-5) break;
      ++it;
      tries = 0;
    } else {
      lambda *= 10.0;
      ++tries;
    }
  }
  return q;
}

}  // namespace

void CylinderFitOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("CylinderFitOptions: ") + what);
  };
  require(max_iterations >= 1 && reweighting_rounds >= 1, "iterations must be >= 1");
  require(huber_scale > 0, "huber_scale must be > 0");
  require(max_slope > 0, "max_slope must be > 0");
}

namespace {

constexpr double kMadToSigma = 1.4826;  // normal sigma per median absolute residual
constexpr double kInlierSigmas = 2.5;   // residuals within this many sigma count into the rms
constexpr double kParams = 5.0;         // x, y, two slopes, radius: degrees of freedom spent

// Iteratively reweighted least squares: per round, the residuals' robust scale (sigma, at least
// huber_scale), the weights of points and tangent rays from it (Huber in the first round with
// huber_first, then the robust weight), and a minimisation with those weights. Leaves the last
// round's residuals and weights in `residuals` and `weights`; returns sigma.
double Reweight(std::span<const Eigen::Vector3d> points, double z_ref, const RadiusPrior& prior,
                std::span<const TangentRay> tangent_rays, const CylinderFitOptions& options,
                Params& q, std::vector<double>& weights, std::vector<double>& residuals,
                Tangents& tangents) {
  double sigma = options.huber_scale;
  for (int round = 0; round <= options.reweighting_rounds; ++round) {
    const AxisFrame frame(q, z_ref);
    for (size_t i = 0; i < points.size(); ++i) {
      residuals[i] = std::abs(Residual(points[i], frame, nullptr));
    }
    std::vector<double> sorted = residuals;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    sigma = std::max(options.huber_scale, kMadToSigma * sorted[sorted.size() / 2]);
    if (round == options.reweighting_rounds) break;
    const bool huber = round == 0 && options.huber_first;
    for (size_t i = 0; i < points.size(); ++i) {
      weights[i] = RobustWeight(residuals[i] / sigma, huber);
    }
    // Tangent rays: the same weights, in units of their own sd.
    for (size_t k = 0; k < tangent_rays.size(); ++k) {
      const double e = TangentResidual(tangent_rays[k], q, z_ref, nullptr);
      tangents.weights[k] = RobustWeight(std::abs(e) / tangent_rays[k].sd, huber);
    }
    q = Minimise(points, weights, q, z_ref, prior, tangents, sigma, options.max_iterations);
  }
  return sigma;
}

// Standard error of the radius: covariance sigma^2 (J^T W J)^-1 at the solution, sigma^2 from the
// weighted residuals; of the measurements alone (points and tangent rays), without the radius
// prior: how well the data show the radius. (A short flat arc held up by the prior has a radius
// the data do not know.)
double RadiusSd(std::span<const Eigen::Vector3d> points, const std::vector<double>& weights,
                const Params& q, double z_ref, const Tangents& tangents, double sigma) {
  Eigen::Matrix<double, 5, 5> jtj;
  Params jte;
  const double weighted2 =
      Cost(points, weights, q, z_ref, RadiusPrior{}, tangents, sigma, &jtj, &jte);
  double weight_sum = 0;
  for (double w : weights) weight_sum += w;
  const double sigma2 = weighted2 / std::max(1.0, weight_sum - kParams);
  const Eigen::Matrix<double, 5, 5> covariance =
      sigma2 * jtj.ldlt().solve(Eigen::Matrix<double, 5, 5>::Identity());
  return std::sqrt(std::max(0.0, covariance(4, 4)));
}

}  // namespace

CylinderFitResult FitCylinder(std::span<const Eigen::Vector3d> points, const Cylinder& initial,
                              const CylinderFitOptions& options, const RadiusPrior& prior,
                              std::span<const TangentRay> tangent_rays) {
  options.Check();
  CylinderFitResult result;
  if (points.size() < 6 || !(initial.radius > 0) || !(initial.direction.z() > 0)) return result;
  const double z_ref = initial.point.z();
  Params q;
  q << initial.point.x(), initial.point.y(), initial.direction.x() / initial.direction.z(),
      initial.direction.y() / initial.direction.z(), initial.radius;
  std::vector<double> weights(points.size(), 1.0), residuals(points.size());
  Tangents tangents{tangent_rays, std::vector<double>(tangent_rays.size(), 1.0)};
  const double sigma =
      Reweight(points, z_ref, prior, tangent_rays, options, q, weights, residuals, tangents);
  if (!q.allFinite() || !(q(4) > 0) || Eigen::Vector2d(q(2), q(3)).norm() > options.max_slope) {
    return result;
  }
  double sum2 = 0;
  for (double e : residuals) {
    if (e > kInlierSigmas * sigma) continue;
    sum2 += e * e;
    ++result.inliers;
  }
  result.rms = result.inliers ? std::sqrt(sum2 / result.inliers) : 0;
  result.radius_sd = RadiusSd(points, weights, q, z_ref, tangents, sigma);
  result.cylinder.point = Eigen::Vector3d(q(0), q(1), z_ref);
  result.cylinder.direction = Eigen::Vector3d(q(2), q(3), 1.0).normalized();
  result.cylinder.radius = q(4);
  result.success = true;
  return result;
}

}  // namespace forestmap::algorithms
