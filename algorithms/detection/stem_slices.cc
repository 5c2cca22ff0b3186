#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "algorithms/detection/stem_model_internal.h"

namespace forestmap::algorithms::internal {
namespace {

// Horizontal offset of a slice centre from the axis at the slice's height.
double AxisOffset(const Axis& axis, const SliceCircle& c) {
  const double t = (c.z - axis.point.z()) / axis.direction.z();
  const Eigen::Vector3d on_axis = axis.point + t * axis.direction;
  return (c.circle.center - on_axis.head<2>()).norm();
}

}  // namespace

double Median(std::vector<double> v) {
  if (v.empty()) return kUnknown;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

namespace {

// A circle's removal band: its inliers and the ring's noise tail within this many bands, or its
// leftovers make small circles.
constexpr double kTailBands = 2.0;
// A partial arc seen from the origin faces it unless it covers at least kFacingCoverage of the
// circle (then it is a stem seen around) or its centre is nearer than its points' mean by more
// than kFacingRadii radii; and the sensor stands at least kSensorClearance (m) outside a stem.
constexpr double kFacingCoverage = 0.5;
constexpr double kFacingRadii = 0.5;
constexpr double kSensorClearance = 0.1;
// Linking slice circles (LinkCircles): a circle links to a chain whose last circle is at most
// kMaxSliceGap slices below it (a stem hidden in a slice or two goes on), of a radius within
// [kMinRadiusRatio, kMaxRadiusRatio] of it, and whose centre lies within link_distance plus
// kLinkRadiusShare of its radius plus the tilt allowance.
constexpr int kMaxSliceGap = 3;
constexpr double kMinRadiusRatio = 0.5;
constexpr double kMaxRadiusRatio = 2.0;
constexpr double kLinkRadiusShare = 0.25;
// A slice centre may lie off the axis by max_centre_offset plus this share of its radius.
constexpr double kCentreRadiusShare = 0.25;
// Stems may touch but not overlap: circles of one slice whose centres are closer than this share
// of their radii's sum overlap (the second is a leftover of the first).
constexpr double kOverlapShare = 0.8;

// The slice's points (every stride-th, at most max_slice_points) into scratch.xy and scratch.z.
void LoadSlice(std::span<const Eigen::Vector3f> points, const std::vector<uint32_t>& members,
               const StemModelOptions& options, SliceScratch& scratch) {
  const size_t stride =
      members.size() > static_cast<size_t>(options.max_slice_points)
          ? (members.size() + options.max_slice_points - 1) / options.max_slice_points
          : 1;
  scratch.xy.clear();
  scratch.z.clear();
  for (size_t k = 0; k < members.size(); k += stride) {
    const Eigen::Vector3f& p = points[members[k]];
    scratch.xy.emplace_back(p.x(), p.y());
    scratch.z.push_back(p.z());
  }
}

// Takes the fit's inliers (and its noise tail) out of scratch.xy and scratch.z; sets the circle's
// z and min_z from them and returns their mean x, y.
Eigen::Vector2d TakeInliers(const CircleFitResult& fit, SliceScratch& scratch, SliceCircle& sc) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  double z_sum = 0;
  sc.min_z = std::numeric_limits<double>::max();
  size_t kept = 0;
  const double tail = kTailBands * fit.band;
  for (size_t i = 0; i < scratch.xy.size(); ++i) {
    if (fit.inlier_mask[i]) {
      mean += scratch.xy[i];
      z_sum += scratch.z[i];
      sc.min_z = std::min<double>(sc.min_z, scratch.z[i]);
    } else if (std::abs((scratch.xy[i] - sc.circle.center).norm() - sc.circle.radius) >= tail) {
      scratch.xy[kept] = scratch.xy[i];
      scratch.z[kept] = scratch.z[i];
      ++kept;
    }
  }
  scratch.xy.resize(kept);
  scratch.z.resize(kept);
  mean /= fit.inliers;
  sc.z = z_sum / fit.inliers;
  return mean;
}

// A partial arc seen from the origin must bulge towards it: its centre lies farther away than its
// points. An arc curving away is the inside of something (a shrub), not a stem. And the sensor
// cannot stand inside a stem: that is a ring of ground returns around it.
bool FacesSensor(const SliceCircle& sc, const Eigen::Vector2d& mean, double arc_coverage) {
  return (arc_coverage >= kFacingCoverage ||
          sc.circle.center.norm() >= mean.norm() - kFacingRadii * sc.circle.radius) &&
         sc.circle.center.norm() > sc.circle.radius + kSensorClearance;
}

bool OverlapsAny(const Circle& circle, std::span<const SliceCircle> others) {
  bool overlaps = false;
  for (const SliceCircle& o : others) {
    const Circle& other = o.circle;
    overlaps |=
        (other.center - circle.center).norm() < kOverlapShare * (other.radius + circle.radius);
  }
  return overlaps;
}

}  // namespace

// Extracts up to max_circles_per_slice circles from one slice, each removing its inliers.
void FitSlice(std::span<const Eigen::Vector3f> points, const std::vector<uint32_t>& members,
              int slice, const StemModelOptions& options, std::mt19937& rng, SliceScratch& scratch,
              StemModelStats& stats) {
  LoadSlice(points, members, options, scratch);
  const size_t first_circle = scratch.circles.size();
  for (int c = 0; c < options.max_circles_per_slice; ++c) {
    if (scratch.xy.size() < static_cast<size_t>(options.min_slice_points)) return;
    ++stats.slices_fitted;
    const CircleFitResult fit = FitCircleRobust(scratch.xy, options.circle, rng);
    if (!fit.success || fit.inliers < options.min_slice_points) return;
    SliceCircle sc;
    sc.circle = fit.circle;
    sc.slice = slice;
    sc.inliers = fit.inliers;
    sc.rms = fit.rms;
    sc.coverage = fit.arc_coverage;
    const Eigen::Vector2d mean = TakeInliers(fit, scratch, sc);
    const bool facing = !options.sensor_at_origin || FacesSensor(sc, mean, fit.arc_coverage);
    const bool overlaps = OverlapsAny(sc.circle, std::span(scratch.circles).subspan(first_circle));
    if (facing && !overlaps && sc.coverage >= options.min_slice_coverage) {
      scratch.circles.push_back(sc);
      ++stats.circles;
    }
  }
}

bool ClusterSeed(std::span<const Eigen::Vector3d> cluster, const StemModelOptions& options,
                 std::mt19937& rng, std::vector<SliceCircle>& circles) {
  std::vector<Eigen::Vector2d> xy;
  SliceCircle seed;
  seed.min_z = std::numeric_limits<double>::max();
  for (const Eigen::Vector3d& p : cluster) {
    xy.push_back(p.head<2>());
    seed.z += p.z() / static_cast<double>(cluster.size());
    seed.min_z = std::min(seed.min_z, p.z());
  }
  const CircleFitResult fit = FitCircleRobust(xy, options.circle, rng);
  if (!fit.success) return false;
  seed.circle = fit.circle;
  seed.inliers = fit.inliers;
  seed.rms = fit.rms;
  seed.coverage = fit.arc_coverage;
  circles.push_back(seed);
  return true;
}

// Links slice circles (in slice order) into chains of one stem each.
std::vector<std::vector<int>> LinkCircles(const std::vector<SliceCircle>& circles,
                                          const StemModelOptions& options) {
  std::vector<std::vector<int>> chains;
  const double tan_tilt = std::tan(options.max_tilt);
  for (int i = 0; i < static_cast<int>(circles.size()); ++i) {
    const SliceCircle& c = circles[i];
    int best = -1;
    double best_dist = std::numeric_limits<double>::max();
    for (int k = 0; k < static_cast<int>(chains.size()); ++k) {
      const SliceCircle& last = circles[chains[k].back()];
      if (last.slice >= c.slice || c.slice - last.slice > kMaxSliceGap) continue;
      const double ratio = c.circle.radius / last.circle.radius;
      if (ratio < kMinRadiusRatio || ratio > kMaxRadiusRatio) continue;
      const double dist = (c.circle.center - last.circle.center).norm();
      const double tolerance = options.link_distance + kLinkRadiusShare * last.circle.radius +
                               tan_tilt * std::abs(c.z - last.z);
      if (dist <= tolerance && dist < best_dist) {
        best = k;
        best_dist = dist;
      }
    }
    if (best >= 0) {
      chains[best].push_back(i);
    } else {
      chains.push_back({i});
    }
  }
  return chains;
}

// Weighted principal direction of the slice centres, signed up; vertical for short spans.
Axis FitAxis(const std::vector<SliceCircle>& circles, const std::vector<int>& members,
             double min_span) {
  Axis axis;
  double weight_sum = 0, z_min = std::numeric_limits<double>::max(), z_max = -z_min;
  for (int i : members) {
    const SliceCircle& c = circles[i];
    axis.point += c.inliers * Eigen::Vector3d(c.circle.center.x(), c.circle.center.y(), c.z);
    weight_sum += c.inliers;
    z_min = std::min(z_min, c.z);
    z_max = std::max(z_max, c.z);
  }
  axis.point /= weight_sum;
  if (z_max - z_min < min_span || members.size() < 2) return axis;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int i : members) {
    const SliceCircle& c = circles[i];
    const Eigen::Vector3d d =
        Eigen::Vector3d(c.circle.center.x(), c.circle.center.y(), c.z) - axis.point;
    cov.noalias() += c.inliers * d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  axis.direction = eig.eigenvectors().col(2).normalized();
  if (axis.direction.z() < 0) axis.direction = -axis.direction;
  return axis;
}

// Keeps the slices that agree with the stem's axis and median radius.
std::vector<int> ConsistentSlices(const std::vector<SliceCircle>& circles,
                                  const std::vector<int>& chain, const Axis& axis,
                                  const StemModelOptions& options) {
  std::vector<double> radii;
  for (int i : chain) radii.push_back(circles[i].circle.radius);
  const double median_radius = Median(radii);
  std::vector<int> kept;
  for (int i : chain) {
    const SliceCircle& c = circles[i];
    const bool radius_ok =
        std::abs(c.circle.radius - median_radius) <= options.max_radius_deviation * median_radius;
    const bool centre_ok =
        AxisOffset(axis, c) <= options.max_centre_offset + kCentreRadiusShare * c.circle.radius;
    if (radius_ok && centre_ok) kept.push_back(i);
  }
  return kept;
}

// Loads one cluster into `scratch`: its points (and beams, with a grid), and its points sorted into
// height slices; returns the slice count. Sparse clusters (far stems) get thicker slices, so that
// each holds enough points (points_per_slice).
int SliceCluster(std::span<const Eigen::Vector3f> points, std::span<const float> heights,
                 const std::vector<uint32_t>& cluster, const StemModelOptions& options,
                 const ScanGrid& grid, SliceScratch& scratch) {
  float h_min = std::numeric_limits<float>::max(), h_max = std::numeric_limits<float>::lowest();
  for (uint32_t i : cluster) {
    h_min = std::min(h_min, heights[i]);
    h_max = std::max(h_max, heights[i]);
  }
  const double slice_height =
      std::clamp((h_max - h_min) * options.points_per_slice / static_cast<double>(cluster.size()),
                 options.slice_height, std::max(options.slice_height, options.max_slice_height));
  const int n_slices = static_cast<int>((h_max - h_min) / slice_height) + 1;
  scratch.slices.resize(std::max<size_t>(scratch.slices.size(), n_slices));
  for (int s = 0; s < n_slices; ++s) scratch.slices[s].clear();
  for (uint32_t i : cluster) {
    const int s = std::min(n_slices - 1, static_cast<int>((heights[i] - h_min) / slice_height));
    scratch.slices[s].push_back(i);
  }
  scratch.circles.clear();
  scratch.cluster.clear();
  for (uint32_t i : cluster) scratch.cluster.push_back(points[i].cast<double>());
  scratch.cluster_beams.clear();
  if (!grid.empty()) {
    for (uint32_t i : cluster) scratch.cluster_beams.push_back(grid.beam[i]);
  }
  return n_slices;
}

ChainAxis AxisOfChain(const std::vector<SliceCircle>& circles, const std::vector<int>& chain,
                      const StemModelOptions& options) {
  ChainAxis c{FitAxis(circles, chain, options.min_axis_span), chain, false};
  if (static_cast<int>(chain.size()) >= options.min_slices) {
    c.kept = ConsistentSlices(circles, chain, c.axis, options);
    if (c.kept.size() < chain.size() && !c.kept.empty()) {
      c.axis = FitAxis(circles, c.kept, options.min_axis_span);
      c.kept = ConsistentSlices(circles, chain, c.axis, options);
    }
  }
  c.sparse = static_cast<int>(c.kept.size()) < options.min_slices ||
             c.kept.size() < options.min_consistent_fraction * chain.size();
  if (c.kept.empty()) c.kept.push_back(chain.front());
  return c;
}

}  // namespace forestmap::algorithms::internal
