#include "algorithms/stem_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {
namespace {

struct SliceCircle {
  Circle circle;
  double z = 0;      // m, mean z of the inliers
  double min_z = 0;  // m, lowest inlier
  int slice = 0;
  int inliers = 0;
  double rms = 0;
  double coverage = 0;
  uint32_t begin = 0, end = 0;  // its inliers in Scratch::inliers
};

// Scratch buffers reused over the clusters of one call.
struct Scratch {
  std::vector<std::vector<uint32_t>> slices;
  std::vector<Eigen::Vector2d> xy;
  std::vector<float> z;
  std::vector<SliceCircle> circles;
  std::vector<Eigen::Vector3d> inliers;  // of every circle of the current cluster
};

double Median(std::vector<double> v) {
  if (v.empty()) return kUnknown;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

// Extracts up to max_circles_per_slice circles from one slice, each removing its inliers.
void FitSlice(std::span<const Eigen::Vector3f> points, const std::vector<uint32_t>& members,
              int slice, const StemModelOptions& options, std::mt19937& rng, Scratch& scratch,
              StemModelStats& stats) {
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
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    double z_sum = 0;
    sc.min_z = std::numeric_limits<double>::max();
    size_t kept = 0;
    // Removes the ring's noise tail too (twice the band), or its leftovers make small circles.
    const double tail = 2.0 * fit.band;
    sc.begin = static_cast<uint32_t>(scratch.inliers.size());
    for (size_t i = 0; i < scratch.xy.size(); ++i) {
      if (fit.inlier_mask[i]) {
        scratch.inliers.emplace_back(scratch.xy[i].x(), scratch.xy[i].y(), scratch.z[i]);
        mean += scratch.xy[i];
        z_sum += scratch.z[i];
        sc.min_z = std::min<double>(sc.min_z, scratch.z[i]);
      } else if (std::abs((scratch.xy[i] - sc.circle.center).norm() - sc.circle.radius) >= tail) {
        scratch.xy[kept] = scratch.xy[i];
        scratch.z[kept] = scratch.z[i];
        ++kept;
      }
    }
    sc.end = static_cast<uint32_t>(scratch.inliers.size());
    scratch.xy.resize(kept);
    scratch.z.resize(kept);
    mean /= fit.inliers;
    sc.z = z_sum / fit.inliers;
    // A partial arc seen from the origin must bulge towards it: its centre lies farther away
    // than its points. An arc curving away is the inside of something (a shrub), not a stem.
    // And the sensor cannot stand inside a stem: that is a ring of ground returns around it.
    const bool facing = !options.sensor_at_origin ||
                        ((fit.arc_coverage >= 0.5 ||
                          sc.circle.center.norm() >= mean.norm() - 0.5 * sc.circle.radius) &&
                         sc.circle.center.norm() > sc.circle.radius + 0.1);
    // Stems may touch but not overlap: a circle overlapping one of this slice is a leftover.
    bool overlaps = false;
    for (size_t k = first_circle; k < scratch.circles.size(); ++k) {
      const Circle& other = scratch.circles[k].circle;
      overlaps |=
          (other.center - sc.circle.center).norm() < 0.8 * (other.radius + sc.circle.radius);
    }
    if (facing && !overlaps && sc.coverage >= options.min_slice_coverage) {
      scratch.circles.push_back(sc);
      ++stats.circles;
    }
  }
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
      if (last.slice >= c.slice || c.slice - last.slice > 3) continue;
      const double ratio = c.circle.radius / last.circle.radius;
      if (ratio < 0.5 || ratio > 2.0) continue;
      const double dist = (c.circle.center - last.circle.center).norm();
      const double tolerance =
          options.link_distance + 0.25 * last.circle.radius + tan_tilt * std::abs(c.z - last.z);
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

struct Axis {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
};

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

// Horizontal offset of a slice centre from the axis at the slice's height.
double AxisOffset(const Axis& axis, const SliceCircle& c) {
  const double t = (c.z - axis.point.z()) / axis.direction.z();
  const Eigen::Vector3d on_axis = axis.point + t * axis.direction;
  return (c.circle.center - on_axis.head<2>()).norm();
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
        AxisOffset(axis, c) <= options.max_centre_offset + 0.25 * c.circle.radius;
    if (radius_ok && centre_ok) kept.push_back(i);
  }
  return kept;
}

// Score in [0, 1]: residual term 1 / (1 + (rms / 1.5 cm)^2), coverage term min(1, coverage /
// 0.35) (a single view sees at most ~half a stem), slice term n / (n + 2).
double ScoreStem(double rms, double coverage, int slices) {
  const double residual_term = 1.0 / (1.0 + (rms / 0.015) * (rms / 0.015));
  const double coverage_term = std::min(1.0, coverage / 0.35);
  const double slice_term = slices / (slices + 2.0);
  return std::clamp(residual_term * coverage_term * slice_term, 0.0, 1.0);
}

}  // namespace

void StemModelOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("StemModelOptions: ") + what);
  };
  circle.Check();
  require(slice_height > 0, "slice_height must be > 0");
  require(min_slice_points >= 3, "min_slice_points must be >= 3");
  require(max_slice_points >= min_slice_points, "max_slice_points must be >= min_slice_points");
  require(max_circles_per_slice >= 1, "max_circles_per_slice must be >= 1");
  require(link_distance >= 0, "link_distance must be >= 0");
  require(max_tilt > 0 && max_tilt < M_PI / 2, "max_tilt must be in (0, pi/2)");
  require(min_slices >= 1, "min_slices must be >= 1");
  require(min_consistent_fraction >= 0 && min_consistent_fraction <= 1,
          "min_consistent_fraction must be in [0, 1]");
  require(max_residual > 0, "max_residual must be > 0");
  require(min_dbh >= 0 && max_dbh > min_dbh, "need 0 <= min_dbh < max_dbh");
  require(min_score >= 0 && min_score <= 1, "min_score must be in [0, 1]");
  require(breast_height > 0, "breast_height must be > 0");
  require(beam_divergence >= 0 && divergence_bias_factor >= 0,
          "beam_divergence and divergence_bias_factor must be >= 0");
}

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

namespace {

enum class Reject { kNone, kSlices, kTilt, kResidual, kCoverage, kDbh, kScore };

// Axis, ground point, taper DBH and checks for one chain of slice circles.
// One circle through the inliers of all consistent slices, projected along the axis: a cylinder
// fit. Far stems give a few points per slice, too few for a circle each but plenty together.
double CylinderDiameter(const std::vector<SliceCircle>& circles, const std::vector<int>& kept,
                        const std::vector<Eigen::Vector3d>& inliers, const Axis& axis,
                        double band) {
  const Eigen::Vector3d& a = axis.direction;
  const Eigen::Vector3d u = a.unitOrthogonal(), v = a.cross(u);
  std::vector<Eigen::Vector2d> projected;
  std::vector<double> radii;
  for (int i : kept) {
    radii.push_back(circles[i].circle.radius);
    for (uint32_t k = circles[i].begin; k < circles[i].end; ++k) {
      const Eigen::Vector3d d = inliers[k] - axis.point;
      projected.emplace_back(d.dot(u), d.dot(v));
    }
  }
  Circle circle{Eigen::Vector2d::Zero(), Median(radii)};
  std::vector<Eigen::Vector2d> near;
  for (int pass = 0; pass < 2; ++pass) {
    near.clear();
    for (const Eigen::Vector2d& p : projected) {
      if (std::abs((p - circle.center).norm() - circle.radius) < band) near.push_back(p);
    }
    if (near.size() < 5) return kUnknown;
    circle = RefineCircleGeometric(near, circle, 15).circle;
  }
  return 2.0 * circle.radius;
}

Reject BuildStem(const std::vector<SliceCircle>& circles, const std::vector<int>& chain,
                 const std::vector<Eigen::Vector3d>& inliers, const GroundModel& ground,
                 const StemModelOptions& options, DetectedTrunk& trunk) {
  if (static_cast<int>(chain.size()) < options.min_slices) return Reject::kSlices;
  Axis axis = FitAxis(circles, chain, options.min_axis_span);
  std::vector<int> kept = ConsistentSlices(circles, chain, axis, options);
  if (kept.size() < chain.size() && kept.size() >= 1) {
    axis = FitAxis(circles, kept, options.min_axis_span);
    kept = ConsistentSlices(circles, chain, axis, options);
  }
  if (static_cast<int>(kept.size()) < options.min_slices ||
      kept.size() < options.min_consistent_fraction * chain.size()) {
    return Reject::kSlices;
  }
  if (std::acos(std::clamp(axis.direction.z(), -1.0, 1.0)) > options.max_tilt) {
    return Reject::kTilt;
  }
  const Eigen::Vector3d& a = axis.direction;
  // Tree-ground intersection: fixed-point iteration of "axis z == ground z under it".
  bool ground_known = ground.known();
  double t = 0;
  if (ground_known) {
    for (int it = 0; it < 6 && ground_known; ++it) {
      const Eigen::Vector3d p = axis.point + t * a;
      const double g = ground.Height(p.x(), p.y());
      ground_known = IsKnown(g);
      t = (g - axis.point.z()) / a.z();
    }
  }
  if (!ground_known) {
    double lowest = std::numeric_limits<double>::max();
    for (int i : kept) lowest = std::min(lowest, circles[i].min_z);
    t = (lowest - axis.point.z()) / a.z();
  }
  const Eigen::Vector3d position = axis.point + t * a;

  std::vector<TaperSample> samples;
  std::vector<double> coverages;
  double sum2 = 0;
  int points = 0;
  double s_lo = std::numeric_limits<double>::max(), s_hi = -s_lo;
  for (int i : kept) {
    const SliceCircle& c = circles[i];
    const Eigen::Vector3d centre(c.circle.center.x(), c.circle.center.y(), c.z);
    const double s = (centre - position).dot(a);
    s_lo = std::min(s_lo, s);
    s_hi = std::max(s_hi, s);
    // Horizontal slices of a tilted stem are ellipses whose minor axis is the true diameter.
    // A circle fitted to part of that ellipse lies between the axes: take their geometric mean.
    samples.push_back(
        {s, 2.0 * c.circle.radius * std::sqrt(a.z()), c.inliers * std::max(c.coverage, 0.05)});
    coverages.push_back(c.coverage);
    sum2 += c.rms * c.rms * c.inliers;
    points += c.inliers;
  }
  const double dbh_height = ground_known ? options.breast_height : 0.5 * (s_lo + s_hi);
  TaperFit taper = FitTaper(samples, dbh_height);
  if (points < options.cylinder_fit_points) {
    const double band = options.circle.max_band_factor * options.circle.inlier_distance;
    const double cylinder = CylinderDiameter(circles, kept, inliers, axis, band);
    if (IsKnown(cylinder)) taper.diameter = cylinder;
  }
  trunk.breast_height_point = position + dbh_height * a;
  trunk.range = trunk.breast_height_point.head<2>().norm();
  trunk.raw_dbh = taper.diameter;
  const double footprint = options.sensor_at_origin ? trunk.range * options.beam_divergence : 0;
  const double dbh = taper.diameter - options.divergence_bias_factor * footprint;
  trunk.residual = std::sqrt(sum2 / std::max(points, 1));
  trunk.arc_coverage = Median(coverages);
  trunk.points_used = points;
  trunk.slices = static_cast<int>(kept.size());
  trunk.ground_known = ground_known;
  trunk.ground_z = ground_known ? position.z() : kUnknown;
  trunk.dbh_height = dbh_height;
  trunk.tree.position = position;
  trunk.tree.axis = a;
  trunk.tree.dbh = dbh;
  trunk.tree.score = ScoreStem(trunk.residual, trunk.arc_coverage, trunk.slices);
  if (trunk.residual > options.max_residual) return Reject::kResidual;
  if (trunk.arc_coverage < options.min_arc_coverage) return Reject::kCoverage;
  if (!(dbh >= options.min_dbh && dbh <= options.max_dbh)) return Reject::kDbh;
  if (trunk.tree.score < options.min_score) return Reject::kScore;
  return Reject::kNone;
}

void Count(Reject reject, StemModelStats& stats) {
  switch (reject) {
    case Reject::kSlices:
      ++stats.rejected_slices;
      break;
    case Reject::kTilt:
      ++stats.rejected_tilt;
      break;
    case Reject::kResidual:
      ++stats.rejected_residual;
      break;
    case Reject::kCoverage:
      ++stats.rejected_coverage;
      break;
    case Reject::kDbh:
      ++stats.rejected_dbh;
      break;
    case Reject::kScore:
      ++stats.rejected_score;
      break;
    case Reject::kNone:
      break;
  }
}

// Drops stems whose breast-height point lies inside a better stem (one stem found twice).
void SuppressDuplicates(std::vector<DetectedTrunk>& trunks, StemModelStats& stats) {
  std::sort(trunks.begin(), trunks.end(), [](const DetectedTrunk& a, const DetectedTrunk& b) {
    return a.tree.score * a.points_used > b.tree.score * b.points_used;
  });
  std::vector<DetectedTrunk> kept;
  for (const DetectedTrunk& t : trunks) {
    bool duplicate = false;
    for (const DetectedTrunk& k : kept) {
      const double reach = 0.5 * std::max(t.tree.dbh, k.tree.dbh) + 0.05;
      if ((t.breast_height_point.head<2>() - k.breast_height_point.head<2>()).norm() < reach) {
        duplicate = true;
        break;
      }
    }
    if (duplicate) {
      ++stats.duplicates;
    } else {
      kept.push_back(t);
    }
  }
  std::sort(kept.begin(), kept.end(), [](const DetectedTrunk& a, const DetectedTrunk& b) {
    return a.tree.score > b.tree.score;
  });
  trunks = std::move(kept);
}

}  // namespace

StemModelResult FitStems(std::span<const Eigen::Vector3f> points, std::span<const float> heights,
                         const std::vector<std::vector<uint32_t>>& clusters,
                         const GroundModel& ground, const StemModelOptions& options) {
  options.Check();
  StemModelResult result;
  std::mt19937 rng(options.seed);
  Scratch scratch;
  for (const std::vector<uint32_t>& cluster : clusters) {
    float h_min = std::numeric_limits<float>::max(), h_max = std::numeric_limits<float>::lowest();
    for (uint32_t i : cluster) {
      h_min = std::min(h_min, heights[i]);
      h_max = std::max(h_max, heights[i]);
    }
    // Sparse clusters (far stems) get thicker slices, so that each holds enough points.
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
    scratch.inliers.clear();
    for (int s = 0; s < n_slices; ++s) {
      FitSlice(points, scratch.slices[s], s, options, rng, scratch, result.stats);
    }
    for (const std::vector<int>& chain : LinkCircles(scratch.circles, options)) {
      ++result.stats.chains;
      DetectedTrunk trunk;
      const Reject reject =
          BuildStem(scratch.circles, chain, scratch.inliers, ground, options, trunk);
      Count(reject, result.stats);
      if (reject == Reject::kNone) result.trunks.push_back(trunk);
    }
  }
  SuppressDuplicates(result.trunks, result.stats);
  return result;
}

}  // namespace forestmap::algorithms
