#pragma once
// From a cluster of stem-layer points to stems: per-slice circles, stem axis, taper, DBH.
//
// 1. The cluster is cut into horizontal slices (slice_height). Each slice may hold several stems
//    (touching trunks, a stem in a shrub), so circles are extracted one after the other by RANSAC
//    (circle_fit.h), each removing its inliers, up to max_circles_per_slice: the per-slice circle
//    count is what splits clusters that DBSCAN merged (the weakness of Zmeškalová 2023,
//    sec. 3.1.1).
// 2. Circles of successive slices are linked into stems when their centres agree (allowing for
//    the stem's tilt), like the stem sections of the backpack paper (Holmgren et al. 2017,
//    sec. 2.4).
// 3. Each chain seeds one cylinder (cylinder_fit.h, Zmeškalová 2023, sec. 4.2.1): the chain's axis
// (the
//    weighted principal direction of its consistent slice centres) and median radius, or for a
//    chain of too few consistent slices (and, in a single view, for a small cluster without any
//    stem: a circle through all its points) a vertical axis through its circle. The stem's points
//    are gathered from the whole cluster around the seed and a robust 5-parameter cylinder is
//    fitted through them (stem_cylinder.cc): far stems give two to four returns per beam ring,
//    too few for a circle per slice but plenty together. In a single view the stem's silhouette
//    holds the radius, so that short flat arcs do not run away to huge circles. With the
//    organised scan (ScanGrid) the silhouette is occlusion-aware (stem_silhouette.cc): per beam
//    ring, an end of the stem's run of columns is its true outline only where the next beam
//    returned from behind the stem (or not at all); where it hit something nearer, the stem is
//    hidden there. The true edges enter the fit as tangent rays (grazing rays, distance from the
//    axis = r), the visible width only as a lower bound. Without a grid, the width of the points
//    seen from the sensor (less a column, plus the footprint's edge returns) is a prior on r.
// 4. Position: where the cylinder's axis (or the slice axis, when no cylinder fits) meets the
//    ground model (Zmeškalová 2023, sec. 5.3), or, without ground, the axis point at the lowest
//    stem point.
// 5. DBH: a weighted, outlier-resistant fit of diameter against distance along the stem, the
//    cubic of Holmgren et al. 2017, eq. 1, d(h) = p1 h^3 + p2 h^2 + p3 h + p4, lowered to a smaller
//    degree when the samples span too little of the stem to carry a cubic, evaluated at
//    breast_height (1.3 m) along the stem; without ground at the middle of the stem seen. The
//    samples are twice the mean distance of the cylinder's points from its axis per slice (a
//    radius given the axis is well determined where a circle per slice is not), or the slice
//    circles when no cylinder fits. With a ScanGrid the DBH is the cylinder's diameter (its
//    tangent rays measure the outline; the points' mean distance grows with the edge returns)
//    carried by that taper from the points' mean height to breast_height. And the DBH is only
//    reported where the scan measures it (min_edge_rings, min_visible_columns, max_off_centre,
//    max_radius_sd): a stem hidden at both edges, seen in a few columns, is a strip that fits a
//    thin stem as well as a wide one, and then the honest DBH is unknown (kUnknown).
// 6. Beam-divergence compensation (the mixed-pixel edge effect): a beam of full divergence angle
//    `beam_divergence` has a footprint of range * beam_divergence; at the silhouette edges of a
//    stem a beam whose centre already misses the stem still returns from it, so the edge points
//    sit up to half a footprint outside the true outline and the arc fit grows. The model:
//    dbh = dbh_fit - divergence_bias_factor * range * beam_divergence. Off when the divergence is
//    0 (the default: a simulator without divergence, or a cloud merged from many ranges). With a
//    ScanGrid the tangent rays are moved inwards instead (edge_bias_factor).
// 7. Rejection of non-stems: too few consistent slices (or too few cylinder points), tilt, fit
//    residual, arc coverage, DBH range, shape (seen over less height than min_elongation DBH, or,
//    in a single view with a known angular_step, a beam fill under min_beam_fill: a crown or a
//    shrub lets most beams through, a stem does not), score below min_score.
//    Score in [0, 1] = residual term * coverage term * slice term (see ScoreStem in the .cc).

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/detection/circle_fit.h"
#include "algorithms/detection/ground_model.h"

namespace forestmap::algorithms {

struct StemModelOptions {
  double slice_height = 0.25;            // m, thinnest slices
  double max_slice_height = 0.8;         // m, thickest slices (sparse clusters)
  int points_per_slice = 14;             // points a sparse cluster's thicker slices aim to hold
  int min_slice_points = 4;              // points (and circle inliers) per slice fit
  int max_slice_points = 1500;           // points; denser slices are thinned evenly
  int max_circles_per_slice = 3;         // stems per slice of one cluster
  CircleRansacOptions circle;            // per-slice RANSAC circle fit
  double min_slice_coverage = 0.08;      // [0, 1], arc coverage of a slice circle
  double link_distance = 0.06;           // m, centre distance of linked slices (plus 0.25 r)
  double max_tilt = 0.5;                 // rad from +z; also the link allowance per metre
  int min_slices = 2;                    // consistent slices per stem
  double min_axis_span = 0.6;            // m, slice centres spanning less: vertical axis
  double max_centre_offset = 0.04;       // m (plus 0.25 r), slice centre off the axis
  double max_radius_deviation = 0.3;     // share of the median radius a slice may differ
  double min_consistent_fraction = 0.6;  // [0, 1], of the linked slices
  double max_residual = 0.025;           // m, stem rms of the circle inliers
  double min_arc_coverage = 0.08;        // [0, 1], median over slices (3 of 36 sectors)
  double min_elongation = 1.5;           // m of visible stem height per m of DBH, at least
  double min_beam_fill = 0.6;            // [0, 1], beams across a stem that return from it
  double min_dbh = 0.05;                 // m
  double max_dbh = 1.2;                  // m
  double min_score = 0.12;               // [0, 1], weaker stems dropped
  double breast_height = 1.3;            // m along the stem above the ground point
  int min_cylinder_points = 10;          // points a stem of < min_slices slices needs
  int max_seed_cluster_points = 300;     // points; smaller stemless clusters get a seed circle
  bool sensor_at_origin = true;          // single viewpoint at (0,0,0): arcs must face it
  double beam_divergence = 0;            // rad, full angle; 0 disables the compensation
  double divergence_bias_factor = 0.1;   // share of the footprint taken off the fitted DBH
  bool silhouette_prior = true;          // the silhouette informs the cylinder fit
  double angular_step = 0;               // rad, horizontal beam spacing; 0: unknown
  double silhouette_bias_factor = 1.33;  // footprints of edge returns in the points' width
  double edge_bias_factor = 0.6;         // footprints of edge returns in a ring's width (grid)
  double taper_prior = 0.01;             // m of diameter per m of stem, lower stem's taper
  int min_edge_rings = 1;                // rings with both edges true for a measured DBH
  double min_edge_columns = 2;           // columns (median) those rings span, at least
  double min_visible_columns = 4;        // columns (median) that measure the DBH without them
  double max_off_centre = 0.3;           // [0, 1], rings nearest off the middle: two stems
  double max_radius_sd = 0.0125;         // m, standard error of the cylinder's radius
  uint32_t seed = 1;                     // RANSAC
  bool keep_rejected = false;            // diagnostics: fill StemModelResult::rejected
  void Check() const;
};

// One detected stem with its diagnostics (sensor frame, metres).
struct DetectedTrunk {
  DetectedTree tree;  // position: tree-ground intersection (or lowest stem point); axis up
  Eigen::Vector3d breast_height_point = Eigen::Vector3d::Zero();  // axis point where dbh applies
  bool ground_known = false;
  double ground_z = kUnknown;   // m, ground height under the stem
  double dbh_height = 0;        // m along the axis from `position` where dbh was evaluated
  double raw_dbh = kUnknown;    // m, before the beam-divergence compensation (a guess when the
                                // dbh is unknown)
  int points_used = 0;          // circle inliers over all slices
  int slices = 0;               // consistent slices
  double residual = 0;          // m, rms of the circle inliers
  double arc_coverage = 0;      // [0, 1], median slice coverage
  double range = 0;             // m, horizontal distance of the breast-height point from 0
  double silhouette_width = 0;  // m, the stem's width seen from the origin (with a ScanGrid:
                                // between true edges; a lower bound when silhouette_rings is 0)
  int silhouette_rings = 0;     // beam rings whose both silhouette edges are true outline (the
                                // beam beside the stem returned from behind it or not at all)
  int occluded_rings = 0;       // beam rings with an edge hidden by something nearer
  int true_edges = 0;           // silhouette edges (of either side, over the rings) that are true
  double visible_columns = 0;   // median columns the stem spans per ring (with a ScanGrid)
  double off_centre = 0;        // [0, 1], share of the wide full rings whose nearest point is off
                                // the middle of the silhouette (see max_off_centre)
  bool dbh_measured = true;     // false: tree.dbh is unknown (see min_edge_rings); raw_dbh holds
                                // the guess
  double cylinder_dbh = kUnknown;  // m, twice the fitted cylinder's radius (over the heights seen)
  double cylinder_height = 0;      // m along the axis from `position`: the cylinder points' mean
  double radius_sd = 0;            // m, standard error of the cylinder fit's radius (points and
                                   // tangent rays; the prior left out)
  double beam_fill = 1;            // [0, 1], share of the beams across the stem that hit it
};

// Diameter at a height along the stem from (height, diameter, weight) samples.
struct TaperSample {
  double height = 0;    // m along the stem
  double diameter = 0;  // m
  double weight = 1;
};
struct TaperFit {
  double diameter = kUnknown;  // m at the requested height
  int degree = 0;              // polynomial degree used (3 = Holmgren eq. 1)
};
TaperFit FitTaper(std::span<const TaperSample> samples, double height);

struct StemModelStats {
  size_t slices_fitted = 0;    // slice fits attempted
  size_t circles = 0;          // slice circles accepted
  size_t chains = 0;           // linked stems considered
  size_t rejected_slices = 0;  // too few consistent slices
  size_t rejected_tilt = 0;
  size_t rejected_residual = 0;
  size_t rejected_coverage = 0;
  size_t rejected_dbh = 0;
  size_t rejected_score = 0;
  size_t rejected_shape = 0;  // not stem-like: short (min_elongation) or porous (min_beam_fill)
  size_t duplicates = 0;      // stems found twice, dropped
};

enum class StemRejection { kNone, kSlices, kTilt, kResidual, kCoverage, kDbh, kScore, kShape };

// A linked stem that failed a check (StemModelOptions::keep_rejected), for diagnosis.
struct RejectedStem {
  DetectedTrunk trunk;  // as far as it was built (kSlices: only the chain's first circle)
  StemRejection reason = StemRejection::kNone;
  int chain_slices = 0;  // slice circles linked
};

// The organised scan behind the points (optional; DetectTrunks builds it for an organised cloud,
// MakeScanGrid in trunk_detection.h): every beam's return and each point's beam. A single view's
// silhouette edge of a stem is only its true outline where the beam beside it returned from
// farther away (or not at all); where that beam hit something nearer, the stem is hidden there
// and its visible width is only a lower bound (see silhouette_prior). A view: it does not own the
// cloud or the indices, which must outlive it.
struct ScanGrid {
  int rings = 0;
  int columns = 0;                           // beams per ring over one full revolution
  double azimuth_step = 0;                   // rad from one column to the next, signed (turn)
  std::span<const Eigen::Vector3f> returns;  // per beam (ring * columns + column), m from the
                                             // sensor at the origin; NaN: no return
  std::span<const uint32_t> beam;            // per point given to FitStems: its beam
  bool empty() const { return returns.empty(); }
  double Range(int ring, int column) const { return returns[ring * columns + column].norm(); }
};

struct StemModelResult {
  std::vector<DetectedTrunk> trunks;   // best score first
  std::vector<RejectedStem> rejected;  // only with keep_rejected
  StemModelStats stats;
};

// `heights` per point: above ground (ground.known()) or above the lowest point.
// `grid`: the organised scan behind `points` (empty: unknown; then the silhouette comes from the
// points alone and cannot tell occluded edges from true ones).
StemModelResult FitStems(std::span<const Eigen::Vector3f> points, std::span<const float> heights,
                         const std::vector<std::vector<uint32_t>>& clusters,
                         const GroundModel& ground, const StemModelOptions& options,
                         const ScanGrid& grid = ScanGrid{});

}  // namespace forestmap::algorithms
