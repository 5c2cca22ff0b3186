#pragma once
// Internal stages of FitStems (stem_model.h), shared by its four source files:
//   stem_slices.cc    circles per slice (RANSAC), linking them into chains, the chain's axis
//   stem_cylinder.cc  a stem's points gathered from its cluster, one cylinder through them (with
//                     the silhouette prior or its tangent rays), and the diameters along it
//   stem_silhouette.cc  the silhouette in the organised scan: true edges told from hidden ones
//   stem_model.cc     the stem from a chain: axis, ground point, DBH, checks, duplicates

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <span>
#include <vector>

#include "algorithms/detection/circle_fit.h"
#include "algorithms/detection/cylinder_fit.h"
#include "algorithms/detection/stem_model.h"

namespace forestmap::algorithms::internal {

double Median(std::vector<double> v);  // kUnknown for an empty vector

struct SliceCircle {
  Circle circle;
  double z = 0;      // m, mean z of the inliers
  double min_z = 0;  // m, lowest inlier
  int slice = 0;
  int inliers = 0;
  double rms = 0;
  double coverage = 0;
};

// Buffers reused over the clusters of one FitStems call.
struct SliceScratch {
  std::vector<uint32_t> cluster_beams;  // the current cluster's beams (with a ScanGrid)
  std::vector<std::vector<uint32_t>> slices;
  std::vector<Eigen::Vector2d> xy;
  std::vector<float> z;
  std::vector<SliceCircle> circles;      // of the current cluster
  std::vector<Eigen::Vector3d> cluster;  // the current cluster's points
};

// Loads one cluster into `scratch` (its points, beams with a grid, and its points sorted into
// height slices, thicker for sparse clusters: points_per_slice); returns the slice count.
int SliceCluster(std::span<const Eigen::Vector3f> points, std::span<const float> heights,
                 const std::vector<uint32_t>& cluster, const StemModelOptions& options,
                 const ScanGrid& grid, SliceScratch& scratch);

// Appends up to max_circles_per_slice circles of one slice to scratch.circles.
void FitSlice(std::span<const Eigen::Vector3f> points, const std::vector<uint32_t>& members,
              int slice, const StemModelOptions& options, std::mt19937& rng, SliceScratch& scratch,
              StemModelStats& stats);

// A circle through the x, y of all the cluster's points (RANSAC), appended to `circles` as one
// more slice circle; false when none fits.
bool ClusterSeed(std::span<const Eigen::Vector3d> cluster, const StemModelOptions& options,
                 std::mt19937& rng, std::vector<SliceCircle>& circles);

// Links slice circles (in slice order) into chains of one stem each (indices into circles).
std::vector<std::vector<int>> LinkCircles(const std::vector<SliceCircle>& circles,
                                          const StemModelOptions& options);

struct Axis {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
};

// Weighted principal direction of the slice centres, signed up; vertical for short spans.
Axis FitAxis(const std::vector<SliceCircle>& circles, const std::vector<int>& members,
             double min_span);

// The chain's axis from its slice centres and the slices consistent with it. `sparse`: too few
// consistent slices for a stem; the first circle only seeds a cylinder then (vertical axis).
struct ChainAxis {
  Axis axis;
  std::vector<int> kept;
  bool sparse = false;
};
ChainAxis AxisOfChain(const std::vector<SliceCircle>& circles, const std::vector<int>& chain,
                      const StemModelOptions& options);

// The chain's slices that agree with the axis and the median radius.
std::vector<int> ConsistentSlices(const std::vector<SliceCircle>& circles,
                                  const std::vector<int>& chain, const Axis& axis,
                                  const StemModelOptions& options);

// A stem's silhouette in the organised scan: per beam ring, the run of columns its points span,
// and whether each end of the run is the stem's true outline (the next beam returned from
// farther than the stem by at least kBackgroundGap, or not at all) or hidden (it returned from
// nearer: an occluder). `width` is the mean of the middle half, over the rings with both ends
// true, of the width those columns span at the axis's distance (n columns, less the footprint's
// edge returns: edge_bias_factor); without such rings, `lower` is a lower bound from all rings.
struct EdgeSilhouette {
  double width = 0;        // m, from the rings with both edges true (0: none)
  double lower = 0;        // m, median width over all rings (a lower bound when edges are hidden)
  int full_rings = 0;      // rings with both edges true
  int occluded_rings = 0;  // rings with at least one edge hidden by something nearer
  int rings = 0;
  double columns = 0;     // median over the rings of the columns the stem spans
  int true_edges = 0;     // of either side, over the rings
  double off_centre = 0;  // share of the rings with both edges true and >= 5 columns whose
                          // nearest point is off the silhouette's middle
  std::vector<TangentRay> tangents;  // the true edges, for the cylinder fit
};

// A stem's points gathered from its whole cluster and one cylinder through them. Far stems give a
// few points per slice, too few for a circle each (or for a second linked slice) but plenty
// together; and a stem found in two slices has more points in the others.
struct GatheredStem {
  CylinderFitResult fit;
  std::vector<Eigen::Vector3d> points;  // within the fit's inlier band
  double coverage = 0;                  // arc coverage around the axis
  std::vector<uint32_t> beams;          // the points' beams (with a ScanGrid)
  double silhouette = 0;                // m, see SilhouetteWidth / EdgeSilhouette
  EdgeSilhouette edges;                 // with a ScanGrid (all zero without one)
  double beam_fill = 1;                 // [0, 1], see BeamFill (1 when unknown)
  double z_lo = 0, z_hi = 0;            // m, height range of the points
};

// A stem's points within `reach` + `lean` * |z - seed height| of the seed's surface gathered
// from its cluster and a robust cylinder through them, `fits` times, each time gathering within
// 2.5 rms (>= 2 cm) of the last fit; then the points within that band of the final cylinder.
// With the sensor at the origin the silhouette informs the fit: with a grid (`beams`: the beam of
// each cluster point) the true edges as tangent rays and the visible width as a lower bound,
// without one the width of the points seen from the origin as a prior (SilhouettePrior).
GatheredStem GatherStem(std::span<const Eigen::Vector3d> cluster, std::span<const uint32_t> beams,
                        const ScanGrid& grid, const Cylinder& seed, double reach, double lean,
                        int fits, const StemModelOptions& options);

// The silhouette of `points` (each seen by beams[i] of `grid`) around `cylinder`.
EdgeSilhouette EdgeSilhouetteOf(std::span<const Eigen::Vector3d> points,
                                std::span<const uint32_t> beams, const Cylinder& cylinder,
                                const ScanGrid& grid, const StemModelOptions& options);

// Diameters along the stem from the gathered points: per slice_height of stem (s along `axis`
// from `position`), twice the mean distance of its points from the fitted cylinder's axis. A
// radius given the axis is well determined even where a circle per slice is not.
std::vector<TaperSample> RadialProfile(const GatheredStem& stem, const Eigen::Vector3d& position,
                                       const Eigen::Vector3d& axis, double slice_height);

// A trunk is solid: no return comes from inside it, beyond its surface's noise. True unless
// `cluster` holds over half as many points as the stem's surface (trunk.points_used) deeper
// inside `trunk` (axis `axis` from `position`, over [s_lo, s_hi] along it) than 3 rms of its fit
// (at least 2 cm): a circle fitted through a blob of clutter (a shrub, foliage) fails.
bool EmptyInside(std::span<const Eigen::Vector3d> cluster, const Eigen::Vector3d& position,
                 const Eigen::Vector3d& axis, double s_lo, double s_hi, const DetectedTrunk& trunk);

}  // namespace forestmap::algorithms::internal
