#pragma once
// Circle fits to 2-D points (a horizontal stem slice, a planar scan segment), metres.
//
// FitCircleKasa: the algebraic fit of Kasa (1976), minimising sum (x^2 + y^2 + D x + E y + F)^2;
// closed form, biased towards small radii on short noisy arcs, so it only seeds
// RefineCircleGeometric: Levenberg-Marquardt on the geometric residuals |p - c| - r.
// FitCircleRobust: RANSAC over 3-point circles against branches and clutter (MSAC scoring), then
// the geometric refinement on the inliers. A fit on clean points skips the sampling entirely.

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <span>
#include <vector>

namespace forestmap::algorithms {

struct Circle {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // m
  double radius = 0;                                 // m
};

// Kasa algebraic fit; false in `ok` for fewer than 3 points or collinear points.
struct KasaResult {
  bool ok = false;
  Circle circle;
};
KasaResult FitCircleKasa(std::span<const Eigen::Vector2d> points);

// Circle through three points; ok = false when they are (nearly) collinear.
KasaResult CircleFromThreePoints(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                 const Eigen::Vector2d& c);

struct GeometricFitResult {
  Circle circle;
  double rms = 0;      // m, root mean square of |p - c| - r
  int iterations = 0;  // LM iterations run
};
// Levenberg-Marquardt refinement of `initial` over `points` (>= 3 points).
GeometricFitResult RefineCircleGeometric(std::span<const Eigen::Vector2d> points,
                                         const Circle& initial, int max_iterations = 15);

// Share of `bins` equal angular sectors around `center` that hold at least one point, in [0, 1]
// (a single viewpoint sees at most about half of a stem).
double ArcCoverage(std::span<const Eigen::Vector2d> points, const Eigen::Vector2d& center,
                   int bins = 36);

struct CircleRansacOptions {
  double inlier_distance = 0.02;    // m, |distance to the circle| of an inlier
  double min_radius = 0.025;        // m
  double max_radius = 1.0;          // m
  int max_iterations = 60;          // RANSAC samples at most
  double clean_inlier_ratio = 0.9;  // a direct fit with this many inliers skips RANSAC
  int min_points = 5;               // fewer points (or inliers) -> no fit
  // The final inlier band adapts to the measured noise: 2.5 robust sigmas of the residuals,
  // between inlier_distance and max_band_factor * inlier_distance (bark, registration noise).
  double max_band_factor = 2.25;
  void Check() const;
};

struct CircleFitResult {
  bool success = false;
  Circle circle;
  double rms = 0;                    // m, geometric residual over the inliers
  double band = 0;                   // m, the final inlier band (see max_band_factor)
  int inliers = 0;                   // points within inlier_distance of the circle
  double arc_coverage = 0;           // [0, 1], see ArcCoverage
  bool used_ransac = false;          // false: the direct Kasa + LM fit was clean enough
  std::vector<uint8_t> inlier_mask;  // one per input point
};

// Robust fit. `rng` is the caller's, so that a pipeline stays deterministic for a seed.
CircleFitResult FitCircleRobust(std::span<const Eigen::Vector2d> points,
                                const CircleRansacOptions& options, std::mt19937& rng);

}  // namespace forestmap::algorithms
