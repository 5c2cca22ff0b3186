#pragma once
// One straight cylinder (a stem section) fitted to 3-D points, metres.
//
// Per-slice circles need a few points per slice; a far stem gives two to four returns per beam
// ring, too few for a circle per slice but plenty for one cylinder through all of them (Zmeškalová
// 2023, sec. 4.2.1: cylinder fits to the stem points). The model has five parameters: the axis
// point at a fixed reference height (x0, y0), the axis slopes (sx, sy) (direction (sx, sy, 1),
// normalised) and the radius r. A point's residual is its perpendicular distance to the axis minus
// r. Levenberg-Marquardt with analytic derivatives inside iteratively reweighted least squares,
// with sigma = max(huber_scale, 1.4826 MAD of the residuals): Huber weights (1.5 sigma) in the
// first round, from a rough seed, then Tukey's biweight (4.685 sigma), so that a branch, a shrub or
// a neighbouring stem beside the stem does not pull it. An optional prior on the radius
// (RadiusPrior) keeps short, flat arcs from running away to huge radii, and optional tangent rays
// (TangentRay: the silhouette edges a sensor at the origin saw) measure the radius where the arc
// cannot: a far stem's arc bulges less than the range noise, its width does not.

#include <Eigen/Core>
#include <span>

namespace forestmap::algorithms {

struct Cylinder {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();       // m, on the axis
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  // unit, z > 0
  double radius = 0;                                     // m
};

struct CylinderFitOptions {
  int max_iterations = 10;     // LM iterations per reweighting round
  int reweighting_rounds = 3;  // IRLS rounds
  bool huber_first = true;     // Huber weights in the first round (false: Tukey from the start,
                               // for a seed that is already close)
  double huber_scale = 0.015;  // m, the least residual sigma (range noise, bark)
  double max_slope = 0.6;      // axis tilt |(sx, sy)| at most (0.6: 31 deg); steeper = no fit
  void Check() const;
};

struct CylinderFitResult {
  bool success = false;  // converged to a finite cylinder with 0 < r, within max_slope
  Cylinder cylinder;
  double rms = 0;        // m, rms of the residuals of the inliers
  int inliers = 0;       // points within 2.5 sigma of the surface
  double radius_sd = 0;  // m, standard error of the radius from the fit's covariance of the
                         // points and tangent rays (the RadiusPrior left out)
};

// A soft, asymmetric prior on the radius: one pseudo-observation of `radius` with standard
// deviation sd_below for smaller radii and sd_above for larger ones (m). Off when radius <= 0.
// (A single viewpoint sees at most the stem's width, but less of it when it is occluded.)
struct RadiusPrior {
  double radius = 0;
  double sd_below = 0.01;
  double sd_above = 0.01;
};

// A silhouette edge seen from a sensor at the origin: a ray that grazes the stem (between the last
// beam that hit it and the next, which passed it), so its distance from the axis is the radius.
// One pseudo-observation "distance(axis, ray) - r = 0" with standard deviation sd (m), weighted
// like the points (Huber, then Tukey) so that an edge widened by a branch does not pull.
struct TangentRay {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // unit, from the origin
  double sd = 0.01;                                      // m
};

// `initial` seeds the fit (point, direction with z > 0, radius > 0). Needs >= 6 points.
CylinderFitResult FitCylinder(std::span<const Eigen::Vector3d> points, const Cylinder& initial,
                              const CylinderFitOptions& options = {}, const RadiusPrior& prior = {},
                              std::span<const TangentRay> tangents = {});

}  // namespace forestmap::algorithms
