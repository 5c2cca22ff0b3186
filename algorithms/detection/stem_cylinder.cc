#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#include "algorithms/detection/stem_model_internal.h"

namespace forestmap::algorithms::internal {
namespace {

// Hundreds of points fix a cylinder as well as thousands: a fit takes at most this many.
constexpr size_t kMaxFitPoints = 200;
constexpr double kDefaultAngularStep = 2 * M_PI / 2048;  // rad, when the scan's is unknown

// An even subset of `points` of size `count`, the same whatever their order (a hash of each
// point's millimetre coordinates decides), so that a stem's fit does not depend on the cloud's
// point order.
std::vector<Eigen::Vector3d> EvenSubset(std::span<const Eigen::Vector3d> points, size_t count) {
  std::vector<std::pair<uint64_t, size_t>> keys;
  keys.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& p = points[i];
    uint64_t h = 1469598103934665603ull;
    for (int k = 0; k < 3; ++k) {
      h = (h ^ static_cast<uint64_t>(std::llround(p[k] * 1000))) * 1099511628211ull;
    }
    keys.emplace_back(h ^ (h >> 29), i);
  }
  std::nth_element(keys.begin(), keys.begin() + count, keys.end());
  std::vector<Eigen::Vector3d> subset;
  for (size_t k = 0; k < count; ++k) subset.push_back(points[keys[k].second]);
  return subset;
}

// Width (m) of the stem as seen from the origin: per 15 cm of height, the spread of the beams'
// distances from the axis, perpendicular to the line of sight; the median over the heights, so
// that a shrub or a branch beside the stem at some heights does not widen it.
double SilhouetteWidth(std::span<const Eigen::Vector3d> points, const Cylinder& cylinder) {
  constexpr double kBand = 0.15;  // m
  if (points.empty()) return 0;
  double z_min = std::numeric_limits<double>::max();
  for (const Eigen::Vector3d& p : points) z_min = std::min(z_min, p.z());
  std::vector<Eigen::Vector3d> bands;  // lo, hi, count per band
  const Eigen::Vector3d& a = cylinder.direction;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d c = cylinder.point + (p.z() - cylinder.point.z()) / a.z() * a;
    const Eigen::Vector2d u = p.head<2>().normalized();
    const double e = u.x() * c.y() - u.y() * c.x();
    const size_t band = static_cast<size_t>((p.z() - z_min) / kBand);
    if (band >= bands.size()) bands.resize(band + 1, Eigen::Vector3d(1e9, -1e9, 0));
    bands[band] = {std::min(bands[band].x(), e), std::max(bands[band].y(), e), bands[band].z() + 1};
  }
  std::vector<double> widths;
  for (const Eigen::Vector3d& b : bands) {
    if (b.z() >= 2) widths.push_back(b.y() - b.x());
  }
  return widths.empty() ? 0 : Median(widths);
}

// The radius a single viewpoint's silhouette suggests (sensor_at_origin, no ScanGrid): a firm
// lower bound (the sensor saw at least this much of the stem), a loose upper one (occlusion). The
// lateral extent of a stem's points seen from the origin is its width less one angular_step (the
// columns that hit it span one column less), plus the beam footprint's edge returns
// (silhouette_bias_factor * range * beam_divergence; 1.33 calibrated on simulated Ouster scans).
// The prior holds the cylinder fit of short, flat arcs to that width (cylinder_fit.h,
// RadiusPrior). An unknown angular_step (0; DetectTrunks takes 2 pi / columns of an organised
// cloud) is taken as kDefaultAngularStep.
RadiusPrior SilhouettePrior(double silhouette, double range, const StemModelOptions& options) {
  RadiusPrior prior;
  const double step =
      range * (options.angular_step > 0 ? options.angular_step : kDefaultAngularStep);
  // The points span the columns that hit the stem: one column less than its width, on average;
  // the beam footprint's edge returns widen that again (silhouette_bias_factor).
  prior.radius =
      0.5 * (silhouette + step - options.silhouette_bias_factor * range * options.beam_divergence);
  prior.sd_below = 0.005 + 0.25 * step;
  prior.sd_above = 0.02 + 0.5 * step + 0.5 * std::max(prior.radius, 0.0);
  return prior;
}

// The organised scan's visible width (EdgeSilhouetteOf: `lower`) bounds the diameter from below,
// hidden edges or not: this prior only holds the radius up (a strip of a wide stem would fit a
// thin one). The true edges enter the fit as tangent rays.
RadiusPrior EdgePrior(double lower, double range, int columns) {
  RadiusPrior prior;
  const double step = range * 2 * M_PI / columns;
  prior.radius = 0.5 * lower;
  prior.sd_below = 0.005 + 0.25 * step;
  prior.sd_above = 1.0;
  return prior;
}

// Share of the beams across the stem's silhouette that returned from it: per beam ring (points
// of one elevation angle seen from the origin, within 1 mrad), the points over the columns
// spanned (azimuth extent / angular_step + 1). A solid stem returns nearly every beam that
// crosses it; a crown or a shrub lets most of them through to something else.
double BeamFill(std::span<const Eigen::Vector3d> points, const Cylinder& cylinder,
                double angular_step) {
  const Eigen::Vector2d toward = cylinder.point.head<2>().normalized();
  std::vector<Eigen::Vector2d> rays;  // elevation, azimuth relative to the stem
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector2d xy = p.head<2>();
    // Tangents of elevation and of azimuth from the stem's direction (the stem subtends a small
    // angle, where the tangent is the angle; no atan2 per point).
    const double along = toward.dot(xy);
    rays.emplace_back(p.z() / xy.norm(), (toward.x() * xy.y() - toward.y() * xy.x()) / along);
  }
  std::sort(rays.begin(), rays.end(),
            [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() < b.x(); });
  double returned = 0, crossed = 0;
  for (size_t begin = 0; begin < rays.size();) {
    size_t end = begin + 1;
    double lo = rays[begin].y(), hi = lo;
    while (end < rays.size() && rays[end].x() - rays[end - 1].x() < 1e-3) {
      lo = std::min(lo, rays[end].y());
      hi = std::max(hi, rays[end].y());
      ++end;
    }
    returned += static_cast<double>(end - begin);
    crossed += std::round((hi - lo) / angular_step) + 1;
    begin = end;
  }
  return crossed > 0 ? std::min(1.0, returned / crossed) : 0;
}

// After each fit the gather band is the fit's rms times kReachRms, at least kMinReach (m), with no
// lean: the cylinder now follows the stem's tilt.
constexpr double kReachRms = 2.5;
constexpr double kMinReach = 0.02;

// The stem's points within `reach` + `lean` * |z - axis point's z| of the cylinder's surface (and
// their beams, with a grid).
void Gather(std::span<const Eigen::Vector3d> cluster, std::span<const uint32_t> beams,
            bool with_grid, const Cylinder& cylinder, double reach, double lean,
            GatheredStem& stem) {
  stem.points.clear();
  stem.beams.clear();
  for (size_t i = 0; i < cluster.size(); ++i) {
    const Eigen::Vector3d& p = cluster[i];
    const double d = (p - cylinder.point).cross(cylinder.direction).norm();
    if (std::abs(d - cylinder.radius) < reach + lean * std::abs(p.z() - cylinder.point.z())) {
      stem.points.push_back(p);
      if (with_grid) stem.beams.push_back(beams[i]);
    }
  }
}

// What the silhouette tells the fit: with a grid its true edges as tangent rays and the visible
// width as a lower bound on the radius, without one the points' width seen from the origin as a
// prior. Sets stem.silhouette (and stem.edges).
RadiusPrior SilhouetteInputs(const Cylinder& cylinder, bool with_grid, const ScanGrid& grid,
                             const StemModelOptions& options, GatheredStem& stem,
                             std::vector<TangentRay>& tangents) {
  RadiusPrior prior;
  tangents.clear();
  const double range = cylinder.point.head<2>().norm();
  const bool informed = options.sensor_at_origin && options.silhouette_prior;
  if (with_grid) {
    stem.edges = EdgeSilhouetteOf(stem.points, stem.beams, cylinder, grid, options);
    const EdgeSilhouette& edges = stem.edges;
    stem.silhouette = edges.full_rings > 0 ? edges.width : edges.lower;
    if (informed) {
      tangents = edges.tangents;
      if (edges.lower > 0) prior = EdgePrior(edges.lower, range, grid.columns);
    }
  } else {
    stem.silhouette = SilhouetteWidth(stem.points, cylinder);
    if (informed && stem.silhouette > 0) prior = SilhouettePrior(stem.silhouette, range, options);
  }
  return prior;
}

// The points' height range, arc coverage around the axis and beam fill.
void Describe(const Cylinder& cylinder, const StemModelOptions& options, GatheredStem& stem) {
  const Eigen::Vector3d& a = cylinder.direction;
  const Eigen::Vector3d u = a.unitOrthogonal(), v = a.cross(u);
  std::vector<Eigen::Vector2d> projected;
  stem.z_lo = std::numeric_limits<double>::max();
  stem.z_hi = -stem.z_lo;
  for (const Eigen::Vector3d& p : stem.points) {
    projected.emplace_back((p - cylinder.point).dot(u), (p - cylinder.point).dot(v));
    stem.z_lo = std::min(stem.z_lo, p.z());
    stem.z_hi = std::max(stem.z_hi, p.z());
  }
  stem.coverage = ArcCoverage(projected, Eigen::Vector2d::Zero());
  if (options.sensor_at_origin && options.angular_step > 0) {
    stem.beam_fill = BeamFill(stem.points, cylinder, options.angular_step);
  }
}

}  // namespace

GatheredStem GatherStem(std::span<const Eigen::Vector3d> cluster, std::span<const uint32_t> beams,
                        const ScanGrid& grid, const Cylinder& seed, double reach, double lean,
                        int fits, const StemModelOptions& options) {
  GatheredStem stem;
  Cylinder cylinder = seed;
  const bool with_grid = !grid.empty() && beams.size() == cluster.size();
  std::vector<TangentRay> tangents;
  for (int fit = 0; fit < fits; ++fit) {
    Gather(cluster, beams, with_grid, cylinder, reach, lean, stem);
    const RadiusPrior prior = SilhouetteInputs(cylinder, with_grid, grid, options, stem, tangents);
    std::span<const Eigen::Vector3d> fit_points(stem.points);
    std::vector<Eigen::Vector3d> subset;
    if (stem.points.size() > kMaxFitPoints) {
      subset = EvenSubset(stem.points, kMaxFitPoints);
      fit_points = subset;
    }
    stem.fit = FitCylinder(fit_points, cylinder, {}, prior, tangents);
    if (!stem.fit.success) return stem;
    cylinder = stem.fit.cylinder;
    reach = std::max(kMinReach, kReachRms * stem.fit.rms);
    lean = 0;
  }
  Gather(cluster, beams, with_grid, cylinder, reach, lean, stem);  // near the final cylinder
  Describe(cylinder, options, stem);
  return stem;
}

std::vector<TaperSample> RadialProfile(const GatheredStem& stem, const Eigen::Vector3d& position,
                                       const Eigen::Vector3d& axis, double slice_height) {
  const Cylinder& c = stem.fit.cylinder;
  std::vector<Eigen::Vector3d> sums;  // sum of s, sum of distances, count per slice
  for (const Eigen::Vector3d& p : stem.points) {
    const double s = (p - position).dot(axis);
    const size_t k = static_cast<size_t>(std::max(0.0, s / slice_height));
    if (k >= sums.size()) sums.resize(k + 1, Eigen::Vector3d::Zero());
    sums[k] += Eigen::Vector3d(s, (p - c.point).cross(c.direction).norm(), 1.0);
  }
  std::vector<TaperSample> samples;
  for (const Eigen::Vector3d& sum : sums) {
    if (sum.z() >= 3) samples.push_back({sum.x() / sum.z(), 2 * sum.y() / sum.z(), sum.z()});
  }
  if (samples.empty()) samples.push_back({stem.points.empty() ? 0 : 0.0, 2 * c.radius, 1.0});
  return samples;
}

bool EmptyInside(std::span<const Eigen::Vector3d> cluster, const Eigen::Vector3d& position,
                 const Eigen::Vector3d& axis, double s_lo, double s_hi,
                 const DetectedTrunk& trunk) {
  constexpr double kInsideMargin = 0.02;  // m, the least depth below the surface
  constexpr double kMaxInsideShare = 0.5;
  const double dbh = std::isfinite(trunk.cylinder_dbh) ? std::min(trunk.raw_dbh, trunk.cylinder_dbh)
                                                       : trunk.raw_dbh;
  const double radius = 0.5 * dbh - std::max(3 * trunk.residual, kInsideMargin);
  if (!(radius > 0)) return true;
  int inside = 0;
  for (const Eigen::Vector3d& p : cluster) {
    const Eigen::Vector3d v = p - position;
    const double s = v.dot(axis);
    if (s >= s_lo && s <= s_hi && (v - s * axis).norm() < radius) ++inside;
  }
  return inside <= kMaxInsideShare * trunk.points_used;
}

}  // namespace forestmap::algorithms::internal
