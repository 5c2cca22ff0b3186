#include "algorithms/detection/circle_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {
namespace {

// MSAC cost (Torr & Zisserman 2000): truncated squared residual, so that a hypothesis is judged
// by how well its inliers fit, not only by how many there are.
double MsacCost(std::span<const Eigen::Vector2d> points, const Circle& circle, double threshold,
                int* inliers) {
  const double t2 = threshold * threshold;
  double cost = 0;
  int count = 0;
  for (const Eigen::Vector2d& p : points) {
    const double e = (p - circle.center).norm() - circle.radius;
    const double e2 = e * e;
    if (e2 < t2) {
      cost += e2;
      ++count;
    } else {
      cost += t2;
    }
  }
  *inliers = count;
  return cost;
}

int MarkInliers(std::span<const Eigen::Vector2d> points, const Circle& circle, double threshold,
                std::vector<uint8_t>& mask, std::vector<Eigen::Vector2d>& inlier_points) {
  mask.assign(points.size(), 0);
  inlier_points.clear();
  for (size_t i = 0; i < points.size(); ++i) {
    if (std::abs((points[i] - circle.center).norm() - circle.radius) < threshold) {
      mask[i] = 1;
      inlier_points.push_back(points[i]);
    }
  }
  return static_cast<int>(inlier_points.size());
}

// 2.5 robust sigmas (1.4826 MAD) of the residuals near the circle, within [t, factor * t].
double AdaptiveBand(std::span<const Eigen::Vector2d> points, const Circle& circle, double t,
                    double factor) {
  if (factor <= 1.0) return t;
  std::vector<double> residuals;
  residuals.reserve(points.size());
  for (const Eigen::Vector2d& p : points) {
    const double e = std::abs((p - circle.center).norm() - circle.radius);
    if (e < 3.0 * t) residuals.push_back(e);
  }
  if (residuals.size() < 5) return t;
  const size_t mid = residuals.size() / 2;
  std::nth_element(residuals.begin(), residuals.begin() + mid, residuals.end());
  return std::clamp(2.5 * 1.4826 * residuals[mid], t, factor * t);
}

}  // namespace

void CircleRansacOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("CircleRansacOptions: ") + what);
  };
  require(inlier_distance > 0, "inlier_distance must be > 0");
  require(min_radius > 0 && max_radius > min_radius, "need 0 < min_radius < max_radius");
  require(max_iterations >= 1, "max_iterations must be >= 1");
  require(clean_inlier_ratio > 0 && clean_inlier_ratio <= 1, "clean_inlier_ratio in (0, 1]");
  require(min_points >= 3, "min_points must be >= 3");
  require(max_band_factor >= 1, "max_band_factor must be >= 1");
}

KasaResult FitCircleKasa(std::span<const Eigen::Vector2d> points) {
  KasaResult result;
  if (points.size() < 3) return result;
  // Centred coordinates keep the normal equations well conditioned far from the origin.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d q = p - mean;
    const Eigen::Vector3d row(q.x(), q.y(), 1.0);
    const double rhs = -q.squaredNorm();
    ata.noalias() += row * row.transpose();
    atb += row * rhs;
  }
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
  if (ldlt.info() != Eigen::Success || std::abs(ldlt.vectorD().minCoeff()) < 1e-12) {
    return result;
  }
  const Eigen::Vector3d def = ldlt.solve(atb);
  const Eigen::Vector2d center(-0.5 * def.x(), -0.5 * def.y());
  const double r2 = center.squaredNorm() - def.z();
  if (!(r2 > 0) || !std::isfinite(r2)) return result;
  result.ok = true;
  result.circle.center = center + mean;
  result.circle.radius = std::sqrt(r2);
  return result;
}

KasaResult CircleFromThreePoints(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                 const Eigen::Vector2d& c) {
  KasaResult result;
  const Eigen::Vector2d ab = b - a;
  const Eigen::Vector2d ac = c - a;
  const double det = 2.0 * (ab.x() * ac.y() - ab.y() * ac.x());
  const double scale = ab.squaredNorm() * ac.squaredNorm();
  if (std::abs(det) < 1e-9 * std::sqrt(scale) || scale == 0) return result;
  const double ab2 = ab.squaredNorm();
  const double ac2 = ac.squaredNorm();
  const Eigen::Vector2d offset((ac.y() * ab2 - ab.y() * ac2) / det,
                               (ab.x() * ac2 - ac.x() * ab2) / det);
  result.ok = true;
  result.circle.center = a + offset;
  result.circle.radius = offset.norm();
  return result;
}

GeometricFitResult RefineCircleGeometric(std::span<const Eigen::Vector2d> points,
                                         const Circle& initial, int max_iterations) {
  GeometricFitResult result;
  result.circle = initial;
  auto cost_of = [&](const Circle& c) {
    double cost = 0;
    for (const Eigen::Vector2d& p : points) {
      const double e = (p - c.center).norm() - c.radius;
      cost += e * e;
    }
    return cost;
  };
  double cost = cost_of(result.circle);
  double lambda = 1e-3;
  for (int it = 0; it < max_iterations && points.size() >= 3; ++it) {
    result.iterations = it + 1;
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jte = Eigen::Vector3d::Zero();
    for (const Eigen::Vector2d& p : points) {
      const Eigen::Vector2d d = p - result.circle.center;
      const double dist = std::max(d.norm(), 1e-12);
      const Eigen::Vector3d j(-d.x() / dist, -d.y() / dist, -1.0);
      jtj.noalias() += j * j.transpose();
      jte += j * (dist - result.circle.radius);
    }
    bool improved = false;
    for (int tries = 0; tries < 8 && !improved; ++tries) {
      Eigen::Matrix3d damped = jtj;
      damped.diagonal() *= (1.0 + lambda);
      const Eigen::Vector3d step = damped.ldlt().solve(-jte);
      Circle next = result.circle;
      next.center += step.head<2>();
      next.radius += step.z();
      const double next_cost = next.radius > 0 ? cost_of(next) : std::numeric_limits<double>::max();
      if (next_cost < cost) {
        improved = true;
        const double gain = cost - next_cost;
        result.circle = next;
        cost = next_cost;
        lambda = std::max(lambda * 0.1, 1e-9);
        if (gain < 1e-12 * (1.0 + cost) || step.norm() < 1e-7) it = max_iterations;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  result.rms = points.empty() ? 0 : std::sqrt(cost / static_cast<double>(points.size()));
  return result;
}

double ArcCoverage(std::span<const Eigen::Vector2d> points, const Eigen::Vector2d& center,
                   int bins) {
  if (bins <= 0 || points.empty()) return 0;
  uint64_t occupied[4] = {0, 0, 0, 0};  // up to 256 bins without allocating
  bins = std::min(bins, 256);
  int count = 0;
  for (const Eigen::Vector2d& p : points) {
    const double angle = std::atan2(p.y() - center.y(), p.x() - center.x()) + M_PI;
    int bin = static_cast<int>(angle / (2.0 * M_PI) * bins);
    bin = std::clamp(bin, 0, bins - 1);
    uint64_t& word = occupied[bin / 64];
    const uint64_t bit = uint64_t{1} << (bin % 64);
    if (!(word & bit)) {
      word |= bit;
      ++count;
    }
  }
  return static_cast<double>(count) / bins;
}

namespace {

constexpr int kRefineIterations = 10;  // Gauss-Newton steps of each geometric refinement
// Mark-and-refine rounds per band: the second picks up points the first circle just missed.
constexpr int kRefinePasses = 2;
// RANSAC's adaptive stop: iterations for this chance of never drawing an all-inlier sample (99%
// confidence of one); an inlier share w with w^3 above kCertainW3 stops at once, and below
// kNegligibleW3 the bound says nothing (max_iterations stays).
constexpr double kMissProbability = 0.01;
constexpr double kCertainW3 = 0.999;
constexpr double kNegligibleW3 = 1e-6;

bool RadiusOk(const Circle& c, const CircleRansacOptions& options) {
  return c.radius >= options.min_radius && c.radius <= options.max_radius;
}

// The clean case, no sampling: one direct fit, refined, kept when it explains
// clean_inlier_ratio of the points.
bool CleanFit(std::span<const Eigen::Vector2d> points, const CircleRansacOptions& options,
              Circle& best) {
  const KasaResult direct = FitCircleKasa(points);
  if (!direct.ok) return false;
  const GeometricFitResult refined =
      RefineCircleGeometric(points, direct.circle, kRefineIterations);
  int inliers = 0;
  MsacCost(points, refined.circle, options.inlier_distance, &inliers);
  const int n = static_cast<int>(points.size());
  if (!RadiusOk(refined.circle, options) || inliers < options.clean_inlier_ratio * n) return false;
  best = refined.circle;
  return true;
}

// MSAC over circles through three random points, with the adaptive stop; false when no sample
// gave a circle of an allowed radius.
bool RansacFit(std::span<const Eigen::Vector2d> points, const CircleRansacOptions& options,
               std::mt19937& rng, Circle& best) {
  const int n = static_cast<int>(points.size());
  std::uniform_int_distribution<int> pick(0, n - 1);
  bool have_best = false;
  double best_cost = std::numeric_limits<double>::max();
  int needed = options.max_iterations;
  for (int it = 0; it < needed; ++it) {
    const int i = pick(rng);
    int j = pick(rng);
    int k = pick(rng);
    if (i == j || j == k || i == k) continue;
    const KasaResult candidate = CircleFromThreePoints(points[i], points[j], points[k]);
    if (!candidate.ok || !RadiusOk(candidate.circle, options)) continue;
    int inliers = 0;
    const double cost = MsacCost(points, candidate.circle, options.inlier_distance, &inliers);
    if (!(cost < best_cost)) continue;  // (a NaN cost is no better either)
    best_cost = cost;
    best = candidate.circle;
    have_best = true;
    const double w = static_cast<double>(inliers) / n;
    const double w3 = w * w * w;
    if (w3 > kCertainW3) {
      needed = it + 1;
    } else if (w3 > kNegligibleW3) {
      needed =
          std::min(options.max_iterations,
                   static_cast<int>(std::ceil(std::log(kMissProbability) / std::log(1.0 - w3))));
    }
  }
  return have_best;
}

// Refines `best` on its inliers within `band`, kRefinePasses times; false when fewer than three
// inliers remain.
bool RefineOnInliers(std::span<const Eigen::Vector2d> points, double band, Circle& best,
                     std::vector<uint8_t>& mask, std::vector<Eigen::Vector2d>& inlier_points) {
  for (int pass = 0; pass < kRefinePasses; ++pass) {
    if (MarkInliers(points, best, band, mask, inlier_points) < 3) return false;
    best = RefineCircleGeometric(inlier_points, best, kRefineIterations).circle;
  }
  return true;
}

}  // namespace

CircleFitResult FitCircleRobust(std::span<const Eigen::Vector2d> points,
                                const CircleRansacOptions& options, std::mt19937& rng) {
  CircleFitResult result;
  const int n = static_cast<int>(points.size());
  if (n < std::max(3, options.min_points)) return result;
  const double t = options.inlier_distance;
  Circle best;
  if (!CleanFit(points, options, best)) {
    result.used_ransac = true;
    if (!RansacFit(points, options, rng, best)) return result;
  }
  std::vector<Eigen::Vector2d> inlier_points;
  inlier_points.reserve(points.size());
  if (!RefineOnInliers(points, t, best, result.inlier_mask, inlier_points)) return result;
  const double band = AdaptiveBand(points, best, t, options.max_band_factor);
  if (band > t && !RefineOnInliers(points, band, best, result.inlier_mask, inlier_points)) {
    return result;
  }
  result.band = band;
  result.inliers = MarkInliers(points, best, band, result.inlier_mask, inlier_points);
  if (result.inliers < options.min_points || !RadiusOk(best, options)) return result;
  double sum2 = 0;
  for (const Eigen::Vector2d& p : inlier_points) {
    const double e = (p - best.center).norm() - best.radius;
    sum2 += e * e;
  }
  result.rms = std::sqrt(sum2 / result.inliers);
  result.circle = best;
  result.arc_coverage = ArcCoverage(inlier_points, best.center);
  result.success = true;
  return result;
}

}  // namespace forestmap::algorithms
