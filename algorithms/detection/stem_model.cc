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
using internal::ChainAxis;
using internal::GatheredStem;
using internal::Median;
using internal::SliceCircle;

// Score in [0, 1]: residual term 1 / (1 + (rms / kScoreRms)^2), coverage term min(1, coverage /
// kFullCoverage) (a single view sees at most ~half a stem), slice term n / (n + kHalfSlices).
constexpr double kScoreRms = 0.015;     // m, rms that halves the residual term
constexpr double kFullCoverage = 0.35;  // [0, 1], arc coverage of a full coverage term
constexpr double kHalfSlices = 2.0;     // slices that give a slice term of one half

double ScoreStem(double rms, double coverage, int slices) {
  const double residual_term = 1.0 / (1.0 + (rms / kScoreRms) * (rms / kScoreRms));
  const double coverage_term = std::min(1.0, coverage / kFullCoverage);
  const double slice_term = slices / (slices + kHalfSlices);
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

// Fixed-point steps of the tree-ground intersection (GroundPoint).
constexpr int kGroundIterations = 6;
// Weight share a slice circle's diameter keeps however little arc it covers.
constexpr double kMinSampleCoverage = 0.05;
// m beyond a found stem's surface within which a lone circle's centre is on that stem.
constexpr double kFoundStemMargin = 0.1;
// m beyond the larger stem's radius within which two breast-height points are one stem.
constexpr double kDuplicateMargin = 0.05;

// Tree-ground intersection: fixed-point iteration of "axis z == ground z under it"; without
// ground under the stem, the axis point at `lowest_z` (ground_known false).
Eigen::Vector3d GroundPoint(const Axis& axis, const GroundModel& ground, double lowest_z,
                            bool* ground_known) {
  const Eigen::Vector3d& a = axis.direction;
  *ground_known = ground.known();
  double t = 0;
  for (int it = 0; it < kGroundIterations && *ground_known; ++it) {
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
    samples.push_back({s, 2.0 * c.circle.radius * std::sqrt(a.z()),
                       c.inliers * std::max(c.coverage, kMinSampleCoverage)});
  }
  return samples;
}

// Whether the organised scan measures the stem's DBH. A stem hidden at both silhouette edges in
// every ring is a strip of unknown width, and a strip of a few columns fits a thin stem as well as
// a wide one: with a ScanGrid the DBH is reported (DetectedTree::dbh) only for stems with at least
// min_edge_rings rings whose both edges are true and that span at least min_edge_columns columns
// (median over the rings; one column is a width known to +-100%), or whose rings span at least
// min_visible_columns columns; else it is unknown (kUnknown; DetectedTrunk::raw_dbh keeps the
// guess). A stem seen whole is nearest to the sensor in the middle of its silhouette; where most
// rings (of 5 columns or more) are nearest off the middle by over a column plus 30% of the half
// width, the silhouette spans more than one stem (two touching trunks): share > max_off_centre, DBH
// unknown too. And the fit must know the radius: the standard error of the cylinder fit's radius
// (points and tangent rays) at most max_radius_sd (1.25 cm: the DBH within 2.5 cm at one sigma).
bool DbhMeasured(const GatheredStem& stem, const StemModelOptions& options) {
  if (stem.fit.radius_sd > options.max_radius_sd) return false;
  const internal::EdgeSilhouette& edges = stem.edges;
  if (edges.full_rings >= std::max(1, options.min_edge_rings)) {
    return edges.off_centre <= options.max_off_centre && edges.columns >= options.min_edge_columns;
  }
  return edges.columns >= options.min_visible_columns;
}

// The first gather around a chain's seed cylinder (GatherStem): points within kSeedReach +
// kSeedReachPerRadius * r of its surface, the band widening by the lean per metre off the seed's
// height. A sparse chain's axis is a vertical guess through one circle, so its band leans wide and
// a second gather-and-fit round follows the tilt the first fit found; a chain of consistent slices
// has a good axis and needs one round.
constexpr double kSeedReach = 0.05;          // m around the seed cylinder's surface
constexpr double kSeedReachPerRadius = 0.5;  // of the seed radius, added to kSeedReach
constexpr double kSparseLean = 0.12;         // m per m off the seed's height (vertical guess)
constexpr double kChainLean = 0.03;          // m per m off the seed's height (fitted chain axis)
constexpr int kSparseFits = 2;               // gather-and-fit rounds for a sparse chain
constexpr int kChainFits = 1;                // gather-and-fit rounds for a chain of slices

// The stem's points gathered from the cluster around the chain's axis and median slice radius,
// with one cylinder through them.
GatheredStem GatherChainStem(const std::vector<SliceCircle>& circles, const ChainAxis& chain_axis,
                             std::span<const Eigen::Vector3d> cluster,
                             std::span<const uint32_t> beams, const ScanGrid& grid,
                             const StemModelOptions& options) {
  std::vector<double> radii;
  for (int i : chain_axis.kept) radii.push_back(circles[i].circle.radius);
  const double seed_radius = Median(radii);
  const bool sparse = chain_axis.sparse;
  const Axis& axis = chain_axis.axis;
  return internal::GatherStem(
      cluster, beams, grid, Cylinder{axis.point, axis.direction, seed_radius},
      kSeedReach + kSeedReachPerRadius * seed_radius, sparse ? kSparseLean : kChainLean,
      sparse ? kSparseFits : kChainFits, options);
}

// The lowest stem point seen: of the consistent slices' circles and of the gathered points.
double LowestStemZ(const std::vector<SliceCircle>& circles, const std::vector<int>& kept,
                   const GatheredStem& gathered) {
  double lowest = std::numeric_limits<double>::max();
  for (int i : kept) lowest = std::min(lowest, circles[i].min_z);
  if (gathered.fit.success) lowest = std::min(lowest, gathered.z_lo);
  return lowest;
}

// Fit quality and extent along the axis (s from `position`): of the slice circles, or of the
// cylinder for a sparse stem.
struct StemExtent {
  std::vector<double> coverages;
  double sum2 = 0;  // m^2, sum of the inliers' squared residuals
  double s_lo = std::numeric_limits<double>::max(), s_hi = -s_lo;  // m along the axis
  int points = 0;
};

StemExtent ExtentOf(const std::vector<SliceCircle>& circles, const std::vector<int>& kept,
                    const GatheredStem* sparse_stem, const Eigen::Vector3d& position,
                    const Eigen::Vector3d& a) {
  StemExtent e;
  for (int i : kept) {
    const SliceCircle& c = circles[i];
    const double s =
        (Eigen::Vector3d(c.circle.center.x(), c.circle.center.y(), c.z) - position).dot(a);
    e.s_lo = std::min(e.s_lo, s);
    e.s_hi = std::max(e.s_hi, s);
    e.coverages.push_back(c.coverage);
    e.sum2 += c.rms * c.rms * c.inliers;
    e.points += c.inliers;
  }
  if (sparse_stem != nullptr) {
    const GatheredStem& gathered = *sparse_stem;
    const Eigen::Vector3d& c = gathered.fit.cylinder.point;
    e.s_lo = (Eigen::Vector3d(c.x(), c.y(), gathered.z_lo) - position).dot(a);
    e.s_hi = (Eigen::Vector3d(c.x(), c.y(), gathered.z_hi) - position).dot(a);
    e.coverages.assign(1, gathered.coverage);
    e.sum2 = gathered.fit.rms * gathered.fit.rms * gathered.points.size();
    e.points = static_cast<int>(gathered.points.size());
  }
  return e;
}

// The fit's residual, coverage, points and slices (`slices` 0: a sparse stem's, counted over
// its extent).
void FitQuality(const StemExtent& e, int slices, const StemModelOptions& options,
                DetectedTrunk& trunk) {
  trunk.residual = std::sqrt(e.sum2 / std::max(e.points, 1));
  trunk.arc_coverage = Median(e.coverages);
  trunk.points_used = e.points;
  trunk.slices =
      slices == 0 ? 1 + static_cast<int>((e.s_hi - e.s_lo) / options.slice_height) : slices;
}

// The silhouette diagnostics of the gathered stem.
void CopySilhouette(const GatheredStem& gathered, DetectedTrunk& trunk) {
  trunk.silhouette_width = gathered.silhouette;
  trunk.silhouette_rings = gathered.edges.full_rings;
  trunk.occluded_rings = gathered.edges.occluded_rings;
  trunk.true_edges = gathered.edges.true_edges;
  trunk.visible_columns = gathered.edges.columns;
  trunk.off_centre = gathered.edges.off_centre;
}

// With the silhouette's tangent rays in the fit (a ScanGrid), the cylinder's radius is the
// stem's, less the footprint's edge returns (edge_bias_factor), better than the points' mean
// distance from the axis (the edge returns push the points out). It holds at the points' mean
// height, which a drone above sees high on the layer; taper_prior carries it to dbh_height: the
// lower stem's typical taper, about 1 cm of diameter per m (the simulator draws 0.6-1.4 cm/m); a
// stem seen over a metre or two, from a few columns, does not show its own taper, and the radial
// profile's does not hold it. Sets trunk.cylinder_height; returns the diameter at dbh_height.
double GridDiameter(const GatheredStem& gathered, const Eigen::Vector3d& position,
                    const Eigen::Vector3d& a, double dbh_height, const StemModelOptions& options,
                    DetectedTrunk& trunk) {
  double s_mean = 0;
  for (const Eigen::Vector3d& p : gathered.points) s_mean += (p - position).dot(a);
  s_mean /= static_cast<double>(std::max<size_t>(1, gathered.points.size()));
  trunk.cylinder_height = s_mean;
  return 2 * gathered.fit.cylinder.radius + options.taper_prior * (s_mean - dbh_height);
}

// The checks of a built stem (StemModelOptions: max_residual ff.), in order. The shape checks
// reject crowns and shrubs reaching into the stem layer: they are wide and short (a stem is seen
// over at least min_elongation times its DBH in height), and in a single view with a known
// angular_step they let most beams through (a stem is solid: min_beam_fill of the beams across it
// return from it).
Reject CheckStem(const DetectedTrunk& trunk, double span, const StemModelOptions& options) {
  const double dbh = trunk.tree.dbh;
  if (trunk.residual > options.max_residual) return Reject::kResidual;
  if (trunk.arc_coverage < options.min_arc_coverage) return Reject::kCoverage;
  if (!(dbh >= options.min_dbh && dbh <= options.max_dbh)) return Reject::kDbh;
  if (trunk.ground_known && span < options.min_elongation * dbh) return Reject::kShape;
  if (trunk.beam_fill < options.min_beam_fill) return Reject::kShape;
  if (trunk.tree.score < options.min_score) return Reject::kScore;
  return Reject::kNone;
}

// Axis, ground point, DBH and checks for one chain of slice circles. The cylinder through the
// stem's points of the whole cluster gives the axis and the diameters when it fits; a chain of
// too few consistent slices is a stem only through such a cylinder.
Reject BuildStem(const std::vector<SliceCircle>& circles, const std::vector<int>& chain,
                 std::span<const Eigen::Vector3d> cluster, std::span<const uint32_t> beams,
                 const ScanGrid& grid, const GroundModel& ground, const StemModelOptions& options,
                 DetectedTrunk& trunk) {
  ChainAxis chain_axis = internal::AxisOfChain(circles, chain, options);
  const bool sparse = chain_axis.sparse;
  const std::vector<int>& kept = chain_axis.kept;
  Axis& axis = chain_axis.axis;
  const GatheredStem gathered = GatherChainStem(circles, chain_axis, cluster, beams, grid, options);
  const bool fitted = gathered.fit.success;
  // A chain of fewer than min_slices consistent slices is a stem only through a cylinder of
  // min_cylinder_points points spanning min_axis_span.
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
  bool ground_known = false;
  const Eigen::Vector3d position =
      GroundPoint(axis, ground, LowestStemZ(circles, kept, gathered), &ground_known);
  const StemExtent e = ExtentOf(circles, kept, sparse ? &gathered : nullptr, position, a);
  const double dbh_height = ground_known ? options.breast_height : 0.5 * (e.s_lo + e.s_hi);
  const std::vector<TaperSample> samples =
      fitted ? internal::RadialProfile(gathered, position, a, options.slice_height)
             : SliceProfile(circles, kept, position, a);
  CopySilhouette(gathered, trunk);
  // With the organised scan the silhouette is measured (stem_silhouette.cc) where it is one stem's
  // whole outline; else the DBH is left unknown (see min_edge_rings).
  const bool with_grid = fitted && !beams.empty();
  trunk.dbh_measured = !with_grid || DbhMeasured(gathered, options);
  trunk.radius_sd = fitted ? gathered.fit.radius_sd : kUnknown;
  trunk.cylinder_dbh = fitted ? 2 * gathered.fit.cylinder.radius : kUnknown;
  trunk.beam_fill = gathered.beam_fill;
  trunk.breast_height_point = position + dbh_height * a;
  trunk.range = trunk.breast_height_point.head<2>().norm();
  trunk.raw_dbh = with_grid ? GridDiameter(gathered, position, a, dbh_height, options, trunk)
                            : FitTaper(samples, dbh_height).diameter;
  // Beam divergence: edge returns reach half a footprint (range * beam_divergence) past the
  // outline; divergence_bias_factor 0.1 of it calibrated on simulated Ouster scans.
  const double footprint =
      options.sensor_at_origin && !with_grid ? trunk.range * options.beam_divergence : 0;
  FitQuality(e, sparse ? 0 : static_cast<int>(kept.size()), options, trunk);
  trunk.ground_known = ground_known;
  trunk.ground_z = ground_known ? position.z() : kUnknown;
  trunk.dbh_height = dbh_height;
  trunk.tree.position = position;
  trunk.tree.axis = a;
  trunk.tree.dbh = trunk.raw_dbh - options.divergence_bias_factor * footprint;
  trunk.tree.score = ScoreStem(trunk.residual, trunk.arc_coverage, trunk.slices);
  if (!internal::EmptyInside(cluster, position, a, e.s_lo, e.s_hi, trunk)) return Reject::kShape;
  return CheckStem(trunk,
                   fitted ? gathered.z_hi - gathered.z_lo : e.s_hi - e.s_lo + options.slice_height,
                   options);
}

void Count(Reject reject, StemModelStats& stats) {
  // In the order of StemRejection, after kNone.
  size_t* const counters[] = {&stats.rejected_slices,   &stats.rejected_tilt,
                              &stats.rejected_residual, &stats.rejected_coverage,
                              &stats.rejected_dbh,      &stats.rejected_score,
                              &stats.rejected_shape};
  if (reject != Reject::kNone) ++*counters[static_cast<int>(reject) - 1];
}

// True when the circle's centre lies within one of the stems (kFoundStemMargin beyond its
// surface).
bool OnFoundStem(const SliceCircle& c, std::span<const DetectedTrunk> trunks) {
  for (const DetectedTrunk& t : trunks) {
    const Eigen::Vector3d& a = t.tree.axis;
    const Eigen::Vector3d on_axis =
        t.breast_height_point + (c.z - t.breast_height_point.z()) / a.z() * a;
    if ((c.circle.center - on_axis.head<2>()).norm() < 0.5 * t.tree.dbh + kFoundStemMargin)
      return true;
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
      const double reach = 0.5 * std::max(t.tree.dbh, k.tree.dbh) + kDuplicateMargin;
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

// What FitStems shares with each chain of the current cluster.
struct ChainContext {
  const internal::SliceScratch& scratch;
  const ScanGrid& grid;
  const GroundModel& ground;
  const StemModelOptions& options;
  size_t first_trunk;  // the current cluster's first stem in result.trunks
};

// Builds the stem of one chain into `result` (or, with keep_rejected, its rejection). A lone
// circle on a stem already found in the cluster is no second stem.
void TryChain(const std::vector<int>& chain, const ChainContext& ctx, StemModelResult& result) {
  const std::vector<SliceCircle>& circles = ctx.scratch.circles;
  const StemModelOptions& options = ctx.options;
  ++result.stats.chains;
  if (static_cast<int>(chain.size()) < options.min_slices &&
      OnFoundStem(circles[chain.front()], std::span(result.trunks).subspan(ctx.first_trunk))) {
    ++result.stats.duplicates;
    return;
  }
  DetectedTrunk trunk;
  const Reject reject = BuildStem(circles, chain, ctx.scratch.cluster, ctx.scratch.cluster_beams,
                                  ctx.grid, ctx.ground, options, trunk);
  Count(reject, result.stats);
  if (reject == Reject::kNone) {
    result.trunks.push_back(trunk);
  } else if (options.keep_rejected) {
    if (reject == Reject::kSlices || reject == Reject::kTilt) {
      const SliceCircle& c = circles[chain.front()];
      trunk.breast_height_point = Eigen::Vector3d(c.circle.center.x(), c.circle.center.y(), c.z);
      trunk.tree.position = trunk.breast_height_point;
      trunk.tree.dbh = 2 * c.circle.radius;
    }
    result.rejected.push_back({trunk, reject, static_cast<int>(chain.size())});
  }
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
    const int n_slices = internal::SliceCluster(points, heights, cluster, options, grid, scratch);
    for (int s = 0; s < n_slices; ++s) {
      internal::FitSlice(points, scratch.slices[s], s, options, rng, scratch, result.stats);
    }
    // Longest chains first.
    std::vector<std::vector<int>> chains = internal::LinkCircles(scratch.circles, options);
    std::stable_sort(chains.begin(), chains.end(),
                     [](const auto& a, const auto& b) { return a.size() > b.size(); });
    const ChainContext ctx{scratch, grid, ground, options, result.trunks.size()};
    for (const std::vector<int>& chain : chains) TryChain(chain, ctx, result);
    // In a single view, a small cluster without a stem (no slice held enough points for a
    // circle: a far, thin stem) gets one more seed, a circle through all its points. (Merged
    // clouds have no far stems of a few returns per ring; their small clusters are clutter.)
    if (options.sensor_at_origin && result.trunks.size() == ctx.first_trunk &&
        static_cast<int>(cluster.size()) <= options.max_seed_cluster_points &&
        internal::ClusterSeed(scratch.cluster, options, rng, scratch.circles)) {
      TryChain({static_cast<int>(scratch.circles.size()) - 1}, ctx, result);
    }
  }
  SuppressDuplicates(result.trunks, result.stats);
  for (DetectedTrunk& trunk : result.trunks) {
    if (!trunk.dbh_measured) trunk.tree.dbh = kUnknown;
  }
  return result;
}

}  // namespace forestmap::algorithms
