// A stem's silhouette in the organised scan, with occluded edges told from true ones
// (stem_model_internal.h, EdgeSilhouetteOf).
//
// Seen from one viewpoint, a stem of radius r whose axis is D away subtends 2 asin(r / D): the
// width of its silhouette measures the diameter directly, whatever the arc's curvature shows (at
// 15 m the visible arc of a 20 cm stem bulges 2 cm towards the sensor, close to the range noise,
// so the arc alone says little about r). But only where the silhouette is the stem's outline: a
// nearer stem, branch or shrub in front of one side hides part of the stem, and then the visible
// width is smaller than the stem. The organised scan tells them apart: the beam just beyond the
// last column that hit the stem returned either from behind the stem (or not at all: sky), a true
// edge, or from something nearer, a hidden one.

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "algorithms/detection/stem_model_internal.h"

namespace forestmap::algorithms::internal {
namespace {

// m, a beam beside the stem that returned from at least this much farther saw the background.
// (Range noise is 1.5-2 cm; ground behind the lowest stem layer is some decimetres farther.)
constexpr double kBackgroundGap = 0.2;
// m, a beam beside the stem that returned from at least this much nearer hit an occluder.
constexpr double kOccluderGap = 0.05;

// Tangent ray sd: the outline lies anywhere within the column beyond the last hit (uniform: sd
// 0.29 columns), plus a floor (m) for the footprint's randomness and the stem's roughness.
constexpr double kEdgeQuantisation = 0.29;
constexpr double kEdgeFloor = 0.003;
// A vertical stem crosses the columns at the same place in every ring, so the rings' edges share
// one quantisation error: the rays of one side together weigh as kIndependentEdges rays at most.
constexpr double kIndependentEdges = 8.0;
// Rays per side given to the fit: the rings' edges are averaged over groups of consecutive rings.
constexpr int kMaxRaysPerSide = 4;
// Rings spanning fewer columns do not tell where the stem is nearest (off_centre).
constexpr int kMinCentreColumns = 5;

enum class Edge { kTrue, kHidden, kUnclear };

Edge Classify(double neighbour_range, double edge_range) {
  if (!std::isfinite(neighbour_range)) return Edge::kTrue;  // no return: nothing behind
  if (neighbour_range > edge_range + kBackgroundGap) return Edge::kTrue;
  if (neighbour_range < edge_range - kOccluderGap) return Edge::kHidden;
  return Edge::kUnclear;  // something at the stem's depth (a touching branch, a mixed pixel)
}

// Mean of the middle half (the median for fewer than four values). Not the median: in the rings
// of a stem the edge beams return or not with a probability that grows with how much of their
// footprint the stem covers (scan_simulation.h), so the mean of the rings' widths resolves the
// outline within a column, the median does not.
double TrimmedMean(std::vector<double> v) {
  if (v.empty()) return 0;
  if (v.size() < 4) return Median(v);
  std::sort(v.begin(), v.end());
  const size_t lo = v.size() / 4, hi = v.size() - v.size() / 4;
  double sum = 0;
  for (size_t i = lo; i < hi; ++i) sum += v[i];
  return sum / static_cast<double>(hi - lo);
}

// One ring's run of columns on the stem, sorted by column.
struct RunPoint {
  int column = 0;      // offset from the ring's first point
  double range = 0;    // m
  uint32_t point = 0;  // index into the stem's points
  bool operator<(const RunPoint& o) const { return column < o.column; }
};
using Run = std::vector<RunPoint>;

// True when the run's nearest point (ranges smoothed over three columns) lies off the middle of
// the run by more than a column (the flat front, the range noise) plus 30% of the half width: one
// stem seen whole is nearest in the middle of its silhouette, two touching stems are not.
bool OffCentre(const Run& run) {
  const int lo = run.front().column, hi = run.back().column;
  int nearest = lo;
  double best = std::numeric_limits<double>::max();
  for (size_t k = 0; k < run.size(); ++k) {
    const size_t a = k > 0 ? k - 1 : 0, b = std::min(run.size() - 1, k + 1);
    double sum = 0;
    for (size_t j = a; j <= b; ++j) sum += run[j].range;
    const double mean = sum / static_cast<double>(b - a + 1);
    if (mean < best) best = mean, nearest = run[k].column;
  }
  return std::abs(nearest - 0.5 * (lo + hi)) > 1 + 0.3 * 0.5 * (hi - lo);
}

struct EdgePoint {
  Eigen::Vector3d direction;  // unit, from the origin to the last point on the stem
  int side;                   // -1: toward lower columns, +1: higher
  double distance;            // m, horizontal, sensor to axis
};

// The grazing rays of one side: half a column beyond the last beam that hit, less the footprint's
// reach past the outline (edge_bias_factor), averaged over groups of consecutive rings (a
// straight stem's outline moves linearly with height, so a group's mean ray grazes it at the
// group's mean height).
void AddTangents(const std::vector<EdgePoint>& edges, int side, const ScanGrid& grid,
                 const StemModelOptions& options, std::vector<TangentRay>& tangents) {
  int count = 0;
  for (const EdgePoint& e : edges) count += e.side == side;
  if (count == 0) return;
  const int group = (count + kMaxRaysPerSide - 1) / kMaxRaysPerSide;
  const int rays = (count + group - 1) / group;
  const double inward = 0.5 * options.edge_bias_factor * options.beam_divergence;  // rad
  const double turn = side * (0.5 * grid.azimuth_step - (grid.azimuth_step > 0 ? inward : -inward));
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ()).matrix();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double quantisation = 0;
  int in_group = 0, seen = 0;
  for (const EdgePoint& e : edges) {
    if (e.side != side) continue;
    sum += e.direction;
    quantisation += kEdgeQuantisation * std::abs(grid.azimuth_step) * e.distance;
    ++seen;
    if (++in_group < group && seen < count) continue;
    TangentRay ray;
    ray.direction = rotation * sum.normalized();
    // The side's rays together weigh as min(count, kIndependentEdges) single edges.
    ray.sd = (kEdgeFloor + quantisation / in_group) *
             std::sqrt(rays / std::min<double>(count, kIndependentEdges));
    tangents.push_back(ray);
    sum.setZero();
    quantisation = 0;
    in_group = 0;
  }
}

// Column offset from `reference`, in [-columns / 2, columns / 2): a stem spans few columns, so
// this survives the wrap from the last column to the first.
int ColumnOffset(int column, int reference, int columns) {
  int d = (column - reference) % columns;
  if (d < -columns / 2) d += columns;
  if (d >= columns / 2) d -= columns;
  return d;
}

int WrapColumn(int column, int columns) { return ((column % columns) + columns) % columns; }

// One beam ring of the stem's points: the points' run of columns (offsets from `reference`, the
// first point's column) sorted by column, and their mean z.
struct Ring {
  int ring = 0;
  int reference = 0;
  double z = 0;  // m
};

// Reads the ring starting at order[begin] (pairs of beam, point sorted by beam) into `run`;
// advances `begin` past it.
Ring ReadRing(std::span<const Eigen::Vector3d> points,
              const std::vector<std::pair<uint32_t, uint32_t>>& order, int columns, size_t& begin,
              Run& run) {
  Ring r;
  r.ring = static_cast<int>(order[begin].first / columns);
  r.reference = static_cast<int>(order[begin].first % columns);
  run.clear();
  for (; begin < order.size() && static_cast<int>(order[begin].first / columns) == r.ring;
       ++begin) {
    const Eigen::Vector3d& p = points[order[begin].second];
    run.push_back(
        {ColumnOffset(static_cast<int>(order[begin].first % columns), r.reference, columns),
         p.norm(), order[begin].second});
    r.z += p.z();
  }
  r.z /= static_cast<double>(run.size());
  std::sort(run.begin(), run.end());
  return r;
}

// What the rings add up to (EdgeSilhouette's fields before the medians and means).
struct RingSums {
  std::vector<double> full, all, spans;  // widths (m) of rings with both edges true, of all
                                         // rings; columns spanned per ring
  int off_centre = 0, centre_rings = 0;
  std::vector<EdgePoint> edges;  // the true edges
};

// Classifies one ring's edges against the beams beside it and adds its width to `sums`.
void AddRing(const Ring& r, const Run& run, std::span<const Eigen::Vector3d> points,
             const Cylinder& cylinder, const ScanGrid& grid, const StemModelOptions& options,
             RingSums& sums, EdgeSilhouette& result) {
  const int columns = grid.columns;
  const double step = 2 * M_PI / columns;  // rad between columns
  const Eigen::Vector3d& a = cylinder.direction;
  const int lo = run.front().column, hi = run.back().column;
  const Edge left =
      Classify(grid.Range(r.ring, WrapColumn(r.reference + lo - 1, columns)), run.front().range);
  const Edge right =
      Classify(grid.Range(r.ring, WrapColumn(r.reference + hi + 1, columns)), run.back().range);
  // Width at the axis's horizontal distance D of the columns spanned: 2 D sin(n step / 2), less
  // the footprint's edge returns, which reach past the outline: edge_bias_factor * D *
  // beam_divergence (in theory 0.5: an edge beam returns with the share of its footprint on the
  // stem, scan_simulation.h; 0.6 calibrated on simulated Ouster scans, 3,400 stems at 2-20 m with
  // taper_prior: no bias left with range; the points pushed out at the edges pull the fit a little
  // wider still).
  const Eigen::Vector3d on_axis = cylinder.point + (r.z - cylinder.point.z()) / a.z() * a;
  const double distance = on_axis.head<2>().norm();
  const double width = 2 * distance * std::sin(0.5 * (hi - lo + 1) * step) -
                       options.edge_bias_factor * distance * options.beam_divergence;
  ++result.rings;
  sums.all.push_back(width);
  sums.spans.push_back(hi - lo + 1);
  if (left == Edge::kTrue && right == Edge::kTrue) {
    sums.full.push_back(width);
    if (hi - lo + 1 >= kMinCentreColumns) {
      ++sums.centre_rings;
      sums.off_centre += OffCentre(run);
    }
  }
  if (left == Edge::kHidden || right == Edge::kHidden) ++result.occluded_rings;
  if (left == Edge::kTrue) {
    sums.edges.push_back({points[run.front().point].normalized(), -1, distance});
  }
  if (right == Edge::kTrue) {
    sums.edges.push_back({points[run.back().point].normalized(), 1, distance});
  }
}

}  // namespace

EdgeSilhouette EdgeSilhouetteOf(std::span<const Eigen::Vector3d> points,
                                std::span<const uint32_t> beams, const Cylinder& cylinder,
                                const ScanGrid& grid, const StemModelOptions& options) {
  EdgeSilhouette result;
  if (grid.empty() || beams.size() != points.size() || points.empty()) return result;
  std::vector<std::pair<uint32_t, uint32_t>> order;  // beam, point
  order.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) order.emplace_back(beams[i], static_cast<uint32_t>(i));
  std::sort(order.begin(), order.end());
  RingSums sums;
  Run run;
  for (size_t begin = 0; begin < order.size();) {
    const Ring ring = ReadRing(points, order, grid.columns, begin, run);
    AddRing(ring, run, points, cylinder, grid, options, sums, result);
  }
  for (int side : {-1, 1}) AddTangents(sums.edges, side, grid, options, result.tangents);
  result.full_rings = static_cast<int>(sums.full.size());
  result.true_edges = static_cast<int>(sums.edges.size());
  result.off_centre =
      sums.centre_rings > 0 ? static_cast<double>(sums.off_centre) / sums.centre_rings : 0;
  result.width = TrimmedMean(sums.full);
  result.lower = sums.all.empty() ? 0 : Median(sums.all);
  result.columns = sums.spans.empty() ? 0 : Median(sums.spans);
  return result;
}

}  // namespace forestmap::algorithms::internal
