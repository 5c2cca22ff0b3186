#include "algorithms/detection/stem_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "algorithms/detection/stem_model_internal.h"

namespace forestmap::algorithms {
namespace {

using internal::Axis;
using internal::GatheredStem;
using internal::Median;
using internal::SliceCircle;

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
  require(edge_bias_factor >= 0, "edge_bias_factor must be >= 0");
  require(taper_prior >= 0 && taper_prior < 0.1, "taper_prior must be in [0, 0.1) m/m");
  require(min_edge_rings >= 0 && min_edge_columns >= 0 && min_visible_columns >= 0 &&
              max_off_centre >= 0 && max_radius_sd > 0,
          "min_edge_rings, min_edge_columns, min_visible_columns, max_off_centre must be >= 0, "
          "max_radius_sd > 0");
  require(beam_divergence >= 0 && divergence_bias_factor >= 0,
          "beam_divergence and divergence_bias_factor must be >= 0");
}

namespace {

using Reject = StemRejection;

// The chain's axis from its slice centres and the slices consistent with it. `sparse`: too few
// consistent slices for a stem; the first circle only seeds a cylinder then (vertical axis).
struct ChainAxis {
  Axis axis;
  std::vector<int> kept;
  bool sparse = false;
};

ChainAxis AxisOfChain(const std::vector<SliceCircle>& circles, const std::vector<int>& chain,
                      const StemModelOptions& options) {
  ChainAxis c{internal::FitAxis(circles, chain, options.min_axis_span), chain, false};
  if (static_cast<int>(chain.size()) >= options.min_slices) {
    c.kept = internal::ConsistentSlices(circles, chain, c.axis, options);
    if (c.kept.size() < chain.size() && !c.kept.empty()) {
      c.axis = internal::FitAxis(circles, c.kept, options.min_axis_span);
      c.kept = internal::ConsistentSlices(circles, chain, c.axis, options);
    }
  }
  c.sparse = static_cast<int>(c.kept.size()) < options.min_slices ||
             c.kept.size() < options.min_consistent_fraction * chain.size();
  if (c.kept.empty()) c.kept.push_back(chain.front());
  return c;
}

// Tree-ground intersection: fixed-point iteration of "axis z == ground z under it"; without
// ground under the stem, the axis point at `lowest_z` (ground_known false).
Eigen::Vector3d GroundPoint(const Axis& axis, const GroundModel& ground, double lowest_z,
                            bool* ground_known) {
  const Eigen::Vector3d& a = axis.direction;
  *ground_known = ground.known();
  double t = 0;
  for (int it = 0; it < 6 && *ground_known; ++it) {
    const Eigen::Vector3d p = axis.point + t * a;
    const double g = ground.Height(p.x(), p.y());
    *ground_known = IsKnown(g);
    t = (g - axis.point.z()) / a.z();
  }
  if (!*ground_known) t = (lowest_z - axis.point.z()) / a.z();
  return axis.point + t * a;
}

// Diameter samples of the chain's consistent slices (when no cylinder could be fitted).
std::vector<TaperSample> SliceProfile(const std::vector<SliceCircle>& circles,
                                      const std::vector<int>& kept, const Eigen::Vector3d& position,
                                      const Eigen::Vector3d& a) {
  std::vector<TaperSample> samples;
  for (int i : kept) {
    const SliceCircle& c = circles[i];
    const double s =
        (Eigen::Vector3d(c.circle.center.x(), c.circle.center.y(), c.z) - position).dot(a);
    // Horizontal slices of a tilted stem are ellipses whose minor axis is the true diameter.
    // A circle fitted to part of that ellipse lies between the axes: take their geometric mean.
    samples.push_back(
        {s, 2.0 * c.circle.radius * std::sqrt(a.z()), c.inliers * std::max(c.coverage, 0.05)});
  }
  return samples;
}

// Whether the organised scan measures the stem's DBH (StemModelOptions::min_edge_rings ff.).
bool DbhMeasured(const GatheredStem& stem, const StemModelOptions& options) {
  if (stem.fit.radius_sd > options.max_radius_sd) return false;
  const internal::EdgeSilhouette& edges = stem.edges;
  if (edges.full_rings >= std::max(1, options.min_edge_rings)) {
    return edges.off_centre <= options.max_off_centre && edges.columns >= options.min_edge_columns;
  }
  return edges.columns >= options.min_visible_columns;
}

// Axis, ground point, DBH and checks for one chain of slice circles. The cylinder through the
// stem's points of the whole cluster gives the axis and the diameters when it fits; a chain of
// too few consistent slices is a stem only through such a cylinder.
Reject BuildStem(const std::vector<SliceCircle>& circles, const std::vector<int>& chain,
                 std::span<const Eigen::Vector3d> cluster, std::span<const uint32_t> beams,
                 const ScanGrid& grid, const GroundModel& ground, const StemModelOptions& options,
                 DetectedTrunk& trunk) {
  ChainAxis chain_axis = AxisOfChain(circles, chain, options);
  const bool sparse = chain_axis.sparse;
  const std::vector<int>& kept = chain_axis.kept;
  Axis& axis = chain_axis.axis;
  std::vector<double> radii;
  for (int i : kept) radii.push_back(circles[i].circle.radius);
  const double seed_radius = Median(radii);
  const GatheredStem gathered =
      internal::GatherStem(cluster, beams, grid, Cylinder{axis.point, axis.direction, seed_radius},
                           0.05 + 0.5 * seed_radius, sparse ? 0.12 : 0.03, sparse ? 2 : 1, options);
  const bool fitted = gathered.fit.success;
  if (sparse &&
      (!fitted || static_cast<int>(gathered.points.size()) < options.min_cylinder_points ||
       gathered.z_hi - gathered.z_lo < options.min_axis_span)) {
    return Reject::kSlices;
  }
  if (fitted) axis = Axis{gathered.fit.cylinder.point, gathered.fit.cylinder.direction};
  if (std::acos(std::clamp(axis.direction.z(), -1.0, 1.0)) > options.max_tilt) {
    return Reject::kTilt;
  }
  const Eigen::Vector3d& a = axis.direction;
  double lowest = std::numeric_limits<double>::max();
  for (int i : kept) lowest = std::min(lowest, circles[i].min_z);
  if (fitted) lowest = std::min(lowest, gathered.z_lo);
  bool ground_known = false;
  const Eigen::Vector3d position = GroundPoint(axis, ground, lowest, &ground_known);

  // Fit quality: of the slice circles, or of the cylinder for a sparse stem.
  std::vector<double> coverages;
  double sum2 = 0, s_lo = std::numeric_limits<double>::max(), s_hi = -s_lo;
  int points = 0;
  for (int i : kept) {
    const SliceCircle& c = circles[i];
    const double s =
        (Eigen::Vector3d(c.circle.center.x(), c.circle.center.y(), c.z) - position).dot(a);
    s_lo = std::min(s_lo, s);
    s_hi = std::max(s_hi, s);
    coverages.push_back(c.coverage);
    sum2 += c.rms * c.rms * c.inliers;
    points += c.inliers;
  }
  if (sparse) {
    const Eigen::Vector3d& c = gathered.fit.cylinder.point;
    s_lo = (Eigen::Vector3d(c.x(), c.y(), gathered.z_lo) - position).dot(a);
    s_hi = (Eigen::Vector3d(c.x(), c.y(), gathered.z_hi) - position).dot(a);
    coverages.assign(1, gathered.coverage);
    sum2 = gathered.fit.rms * gathered.fit.rms * gathered.points.size();
    points = static_cast<int>(gathered.points.size());
  }
  const double dbh_height = ground_known ? options.breast_height : 0.5 * (s_lo + s_hi);
  const std::vector<TaperSample> samples =
      fitted ? internal::RadialProfile(gathered, position, a, options.slice_height)
             : SliceProfile(circles, kept, position, a);
  const TaperFit taper = FitTaper(samples, dbh_height);
  trunk.silhouette_width = gathered.silhouette;
  trunk.silhouette_rings = gathered.edges.full_rings;
  trunk.occluded_rings = gathered.edges.occluded_rings;
  trunk.true_edges = gathered.edges.true_edges;
  trunk.visible_columns = gathered.edges.columns;
  trunk.off_centre = gathered.edges.off_centre;
  // With the organised scan the silhouette is measured (stem_silhouette.cc) where it is one stem's
  // whole outline; else the DBH is left unknown (see min_edge_rings).
  const bool with_grid = fitted && !beams.empty();
  trunk.dbh_measured = !with_grid || DbhMeasured(gathered, options);
  trunk.radius_sd = fitted ? gathered.fit.radius_sd : kUnknown;
  trunk.cylinder_dbh = fitted ? 2 * gathered.fit.cylinder.radius : kUnknown;
  trunk.beam_fill = gathered.beam_fill;
  trunk.breast_height_point = position + dbh_height * a;
  trunk.range = trunk.breast_height_point.head<2>().norm();
  // With the silhouette's tangent rays in the fit (a ScanGrid), the cylinder's radius is the
  // stem's, less the footprint's edge returns (edge_bias_factor), better than the points' mean
  // distance from the axis (the edge returns push the points out). It holds at the points' mean
  // height, which a drone above sees high on the layer; taper_prior carries it to dbh_height.
  double diameter = taper.diameter;
  if (with_grid) {
    double s_mean = 0;
    for (const Eigen::Vector3d& p : gathered.points) s_mean += (p - position).dot(a);
    s_mean /= static_cast<double>(std::max<size_t>(1, gathered.points.size()));
    diameter = 2 * gathered.fit.cylinder.radius + options.taper_prior * (s_mean - dbh_height);
    trunk.cylinder_height = s_mean;
  }
  trunk.raw_dbh = diameter;
  const double footprint =
      options.sensor_at_origin && !with_grid ? trunk.range * options.beam_divergence : 0;
  const double dbh = diameter - options.divergence_bias_factor * footprint;
  trunk.residual = std::sqrt(sum2 / std::max(points, 1));
  trunk.arc_coverage = Median(coverages);
  trunk.points_used = points;
  trunk.slices = sparse ? 1 + static_cast<int>((s_hi - s_lo) / options.slice_height)
                        : static_cast<int>(kept.size());
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
  const double span = fitted ? gathered.z_hi - gathered.z_lo : s_hi - s_lo + options.slice_height;
  if (ground_known && span < options.min_elongation * dbh) return Reject::kShape;
  if (trunk.beam_fill < options.min_beam_fill) return Reject::kShape;
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
    case Reject::kShape:
      ++stats.rejected_shape;
      break;
    case Reject::kNone:
      break;
  }
}

// True when the circle's centre lies within one of the stems (10 cm beyond its surface).
bool OnFoundStem(const SliceCircle& c, std::span<const DetectedTrunk> trunks) {
  for (const DetectedTrunk& t : trunks) {
    const Eigen::Vector3d& a = t.tree.axis;
    const Eigen::Vector3d on_axis =
        t.breast_height_point + (c.z - t.breast_height_point.z()) / a.z() * a;
    if ((c.circle.center - on_axis.head<2>()).norm() < 0.5 * t.tree.dbh + 0.1) return true;
  }
  return false;
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
                         const GroundModel& ground, const StemModelOptions& options,
                         const ScanGrid& grid) {
  options.Check();
  if (!grid.empty() && grid.beam.size() != points.size()) {
    throw std::invalid_argument("FitStems: grid.beam must hold one beam per point");
  }
  StemModelResult result;
  std::mt19937 rng(options.seed);
  internal::SliceScratch scratch;
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
    scratch.cluster.clear();
    for (uint32_t i : cluster) scratch.cluster.push_back(points[i].cast<double>());
    scratch.cluster_beams.clear();
    if (!grid.empty()) {
      for (uint32_t i : cluster) scratch.cluster_beams.push_back(grid.beam[i]);
    }
    for (int s = 0; s < n_slices; ++s) {
      internal::FitSlice(points, scratch.slices[s], s, options, rng, scratch, result.stats);
    }
    // Longest chains first; a lone circle on a stem already found is no second stem.
    std::vector<std::vector<int>> chains = internal::LinkCircles(scratch.circles, options);
    std::stable_sort(chains.begin(), chains.end(),
                     [](const auto& a, const auto& b) { return a.size() > b.size(); });
    const size_t first_trunk = result.trunks.size();
    auto try_chain = [&](const std::vector<int>& chain) {
      ++result.stats.chains;
      if (static_cast<int>(chain.size()) < options.min_slices &&
          OnFoundStem(scratch.circles[chain.front()],
                      std::span(result.trunks).subspan(first_trunk))) {
        ++result.stats.duplicates;
        return;
      }
      DetectedTrunk trunk;
      const Reject reject = BuildStem(scratch.circles, chain, scratch.cluster,
                                      scratch.cluster_beams, grid, ground, options, trunk);
      Count(reject, result.stats);
      if (reject == Reject::kNone) {
        result.trunks.push_back(trunk);
      } else if (options.keep_rejected) {
        if (reject == Reject::kSlices || reject == Reject::kTilt) {
          const SliceCircle& c = scratch.circles[chain.front()];
          trunk.breast_height_point =
              Eigen::Vector3d(c.circle.center.x(), c.circle.center.y(), c.z);
          trunk.tree.position = trunk.breast_height_point;
          trunk.tree.dbh = 2 * c.circle.radius;
        }
        result.rejected.push_back({trunk, reject, static_cast<int>(chain.size())});
      }
    };
    for (const std::vector<int>& chain : chains) try_chain(chain);
    // In a single view, a small cluster without a stem (no slice held enough points for a
    // circle: a far, thin stem) gets one more seed, a circle through all its points. (Merged
    // clouds have no far stems of a few returns per ring; their small clusters are clutter.)
    if (options.sensor_at_origin && result.trunks.size() == first_trunk &&
        static_cast<int>(cluster.size()) <= options.max_seed_cluster_points &&
        internal::ClusterSeed(scratch.cluster, options, rng, scratch.circles)) {
      try_chain({static_cast<int>(scratch.circles.size()) - 1});
    }
  }
  SuppressDuplicates(result.trunks, result.stats);
  for (DetectedTrunk& trunk : result.trunks) {
    if (!trunk.dbh_measured) trunk.tree.dbh = kUnknown;
  }
  return result;
}

}  // namespace forestmap::algorithms
