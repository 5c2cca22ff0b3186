#include "algorithms/pose_search.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

namespace forestmap::algorithms {
namespace {

// Query triangles among the seeds (the nearest query trees), with the index's side limits
// widened by the matching tolerance, nearest first (by their farthest vertex).
std::vector<Triangle> QueryTriangles(const std::vector<Eigen::Vector2d>& seed_xy,
                                     const MapIndexImpl& m, double tolerance) {
  TriangleOptions tri = m.triangle_options;
  tri.max_side += tolerance;
  tri.min_side = std::max(0.0, tri.min_side - tolerance);
  std::vector<std::vector<uint32_t>> neighbours(seed_xy.size());
  for (uint32_t i = 0; i < seed_xy.size(); ++i) {
    for (uint32_t j = 0; j < seed_xy.size(); ++j) {
      if (i != j && (seed_xy[i] - seed_xy[j]).norm() <= tri.max_side) neighbours[i].push_back(j);
    }
  }
  std::vector<Triangle> triangles = EnumerateTriangles(seed_xy, neighbours, tri);
  // Seeds are sorted by range, so the largest vertex index is the farthest vertex.
  auto farthest = [](const Triangle& t) { return std::max({t.vertex[0], t.vertex[1], t.vertex[2]}); };
  std::stable_sort(triangles.begin(), triangles.end(),
                   [&](const Triangle& a, const Triangle& b) { return farthest(a) < farthest(b); });
  return triangles;
}

// Wald's sequential probability ratio test on the nearest query trees: does a pose put them on
// map trees at the rate of a true pose (quick_check_true_rate) or only as often as chance (the
// occupancy grid's occupied fraction)? Wrong poses are rejected after about four lookups.
class QuickCheck {
 public:
  QuickCheck(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options)
      : m_(m), q_(q) {
    // The nearest trees, interleaved across their ranges: misses cluster (the nearest few
    // detections of a handheld scan are often the operator or brush, absent from the map), and
    // the test assumes independent draws.
    const uint32_t n = static_cast<uint32_t>(std::min<size_t>(q.xy.size(), kMaxChecks));
    for (uint32_t phase = 0; phase < kStride; ++phase) {
      for (uint32_t i = phase; i < n; i += kStride) order_.push_back(i);
    }
    const double p1 = options.quick_check_true_rate;
    const double p0 = std::clamp(m.occupancy->occupied_fraction(), 0.005, 0.5 * p1);
    hit_ = std::log(p1 / p0);
    miss_ = std::log((1 - p1) / (1 - p0));
    accept_ = std::log(1 / options.quick_check_false_accept);
    reject_ = std::log(options.quick_check_false_reject);
  }

  // `skip` are the query trees that generated the pose (they fit by construction).
  // The pose maps p to (c p.x - s p.y + tx, s p.x + c p.y + ty).
  bool Passes(float c, float s, float tx, float ty, const std::array<uint32_t, 3>& skip) const {
    double llr = 0;
    for (uint32_t i : order_) {
      if (i == skip[0] || i == skip[1] || i == skip[2]) continue;
      const Eigen::Vector2d& p = q_.xy[i];
      llr += m_.occupancy->Near(c * p.x() - s * p.y() + tx, s * p.x() + c * p.y() + ty)
                 ? hit_
                 : miss_;
      if (llr >= accept_) return true;
      if (llr <= reject_) return false;
    }
    return false;
  }

 private:
  static constexpr size_t kMaxChecks = 40;
  static constexpr uint32_t kStride = 4;
  const MapIndexImpl& m_;
  const LevelledQuery& q_;
  std::vector<uint32_t> order_;  // query trees in the order they are checked
  double hit_ = 0, miss_ = 0, accept_ = 0, reject_ = 0;
};

// Pose cell for recognising a pose already found (0.5 m x 0.5 m x 1.5 deg).
uint64_t PoseCell(const Rigid2& pose) {
  const int64_t cx = static_cast<int64_t>(std::floor(pose.translation.x() / 0.5));
  const int64_t cy = static_cast<int64_t>(std::floor(pose.translation.y() / 0.5));
  const int64_t cyaw = static_cast<int64_t>(std::floor((pose.yaw + M_PI) / 0.026));
  return (static_cast<uint64_t>(cx & 0xFFFFFF) << 40) |
         (static_cast<uint64_t>(cy & 0xFFFFFF) << 16) | static_cast<uint64_t>(cyaw & 0xFFFF);
}

// One least-squares step on the nearest trees (a triangle's pose can be a few degrees off),
// then the score on them.
void Polish(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
            Hypothesis* h) {
  const double gate = 1.5 * options.inlier_distance;
  const std::vector<Association> matches =
      Associate(m, q, h->pose, gate, options.quick_score_trees);
  if (matches.size() >= 3) {
    Rigid2Accumulator acc;
    for (const Association& a : matches) acc.Add(q.xy[a.query], m.Xy(a.map));
    h->pose = acc.Solve();
  }
  Score(m, q, options.inlier_distance, h, options.quick_score_trees);
}

}  // namespace

std::vector<Association> Associate(const MapIndexImpl& m, const LevelledQuery& q,
                                   const Rigid2& pose, double gate, size_t limit) {
  std::vector<Association> out;
  const double gate2 = gate * gate;
  for (uint32_t i = 0; i < std::min(limit, q.xy.size()); ++i) {
    const Eigen::Vector2d p = pose(q.xy[i]);
    auto [j, d2] = m.positions->Nearest({static_cast<float>(p.x()), static_cast<float>(p.y())});
    if (j >= 0 && d2 <= gate2) out.push_back({i, static_cast<uint32_t>(j), std::sqrt(d2)});
  }
  return out;
}

void Score(const MapIndexImpl& m, const LevelledQuery& q, double inlier_distance, Hypothesis* h,
           size_t limit) {
  const std::vector<Association> inliers = Associate(m, q, h->pose, inlier_distance, limit);
  h->inliers = static_cast<int>(inliers.size());
  h->score = 0;
  double sum2 = 0;
  for (const Association& a : inliers) {
    const double r = a.distance / inlier_distance;
    h->score += 1.0 - r * r;
    sum2 += a.distance * a.distance;
  }
  h->rmse = inliers.empty() ? 0 : std::sqrt(sum2 / inliers.size());
}

void Refine(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
            Hypothesis* h) {
  for (double gate : {1.5 * options.inlier_distance, options.inlier_distance,
                      options.inlier_distance, 0.7 * options.inlier_distance,
                      0.7 * options.inlier_distance}) {
    const std::vector<Association> matches = Associate(m, q, h->pose, gate);
    if (matches.size() < 3) break;
    Rigid2Accumulator acc;
    for (const Association& a : matches) {
      const double r = a.distance / gate;
      acc.Add(q.xy[a.query], m.Xy(a.map), 1.0 - 0.5 * r * r);
    }
    h->pose = acc.Solve();
  }
  Score(m, q, options.inlier_distance, h);
}

int InRange(const LevelledQuery& q, double range) {
  return static_cast<int>(std::count_if(q.xy.begin(), q.xy.end(),
                                        [&](const Eigen::Vector2d& p) { return p.norm() <= range; }));
}

int InliersInRange(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                   const RelocalizerOptions& options) {
  int n = 0;
  for (const Association& a : Associate(m, q, pose, options.inlier_distance)) {
    n += q.xy[a.query].norm() <= options.ratio_range;
  }
  return n;
}

PoseSearchResult SearchPoses(const MapIndexImpl& m, const LevelledQuery& q,
                             const std::optional<PriorPose>& prior,
                             const Eigen::Vector2d& prior_xy, const RelocalizerOptions& options) {
  PoseSearchResult result;
  const size_t seeds = std::min<size_t>(q.xy.size(), options.max_seed_trees);
  const std::vector<Eigen::Vector2d> seed_xy(q.xy.begin(), q.xy.begin() + seeds);
  std::vector<Triangle> triangles = QueryTriangles(seed_xy, m, options.triangle_tolerance);
  if (triangles.size() > static_cast<size_t>(options.max_query_triangles)) {
    triangles.resize(options.max_query_triangles);
  }
  const QuickCheck check(m, q, options);
  const float tolerance = static_cast<float>(options.triangle_tolerance);
  const int decisive = std::max<int>(
      options.min_inliers,
      std::ceil(options.decisive_fraction * std::min<size_t>(q.xy.size(), options.quick_score_trees)));
  const int strong = std::max(2 * options.min_inliers,
                              static_cast<int>(options.decisive_fraction *
                                               InRange(q, options.ratio_range)));
  double best_score = 0;
  std::unordered_set<uint64_t> found_cells;
  const double prior_radius2 = prior ? prior->radius * prior->radius : 0.0;
  size_t stop = triangles.size();
  for (size_t i = 0; i < std::min(stop, triangles.size()); ++i) {
    const Triangle& qt = triangles[i];
    const uint32_t a = qt.vertex[0], b = qt.vertex[1], c = qt.vertex[2];
    // The canonical labels come from sorted side lengths; where two sides are within the
    // tolerance, noise may have swapped them in the map, so the swapped labelling is tried too.
    TriangleFrame frames[3] = {FrameOf(seed_xy[a], seed_xy[b], seed_xy[c])};
    int labellings = 1;
    if (qt.sides[1] - qt.sides[0] < tolerance) frames[labellings++] = FrameOf(seed_xy[b], seed_xy[a], seed_xy[c]);
    if (qt.sides[2] - qt.sides[1] < tolerance) frames[labellings++] = FrameOf(seed_xy[a], seed_xy[c], seed_xy[b]);
    const size_t before = result.hypotheses.size();
    ++result.triangles;
    m.triangles->ForEachMatch(qt.sides, tolerance, [&](const IndexedTriangle& t) {
      const TriangleFrame mt = t.frame();
      for (int l = 0; l < labellings; ++l) {
        const TriangleFrame& qf = frames[l];
        if (qf.turn * mt.turn < 0) continue;  // mirror image: no rigid motion maps it
        // map = R * query + t, with the long sides and the centroids aligned:
        // R = R(map heading) R(query heading)^T.
        const float c = mt.cos_heading * qf.cos_heading + mt.sin_heading * qf.sin_heading;
        const float s = mt.sin_heading * qf.cos_heading - mt.cos_heading * qf.sin_heading;
        const float tx = mt.cx - (c * qf.cx - s * qf.cy), ty = mt.cy - (s * qf.cx + c * qf.cy);
        if (prior && (Eigen::Vector2d(tx, ty) - prior_xy).squaredNorm() > prior_radius2) continue;
        ++result.matches;
        if (!check.Passes(c, s, tx, ty, qt.vertex)) continue;
        Hypothesis h;
        h.pose.yaw = std::atan2(s, c);
        h.pose.translation = {tx, ty};
        if (!found_cells.insert(PoseCell(h.pose)).second) continue;  // found already
        result.hypotheses.push_back(h);
      }
    });
    for (size_t k = before; k < result.hypotheses.size(); ++k) {
      Hypothesis& h = result.hypotheses[k];
      Polish(m, q, options, &h);
      // A pose that explains most nearby trees once refined decides the search, after a few
      // more triangles have had the chance to show a rival.
      if (stop < triangles.size() || h.inliers < decisive || h.score <= best_score) continue;
      best_score = h.score;
      Hypothesis refined = h;
      Refine(m, q, options, &refined);
      if (InliersInRange(m, q, refined.pose, options) >= strong) {
        stop = i + 1 + options.rival_triangles;
      }

    }
  }
  std::sort(result.hypotheses.begin(), result.hypotheses.end(),
            [](const Hypothesis& x, const Hypothesis& y) { return x.score > y.score; });
  return result;
}

}  // namespace forestmap::algorithms
