#include "algorithms/relocalization/pose_search.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "algorithms/relocalization/decoys.h"
#include "algorithms/relocalization/query_triangles.h"
#include "algorithms/relocalization/search_budget.h"
#include "algorithms/relocalization/significance.h"

namespace forestmap::algorithms {
namespace {

// Wald's sequential probability ratio test on query trees: does a pose put them on map trees
// at the rate of a true pose (quick_check_true_rate) or only as often as chance (the occupancy
// grid's occupied fraction)? Wrong poses are rejected after about four lookups.
class QuickCheck {
 public:
  QuickCheck(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options)
      : m_(m), q_(q), quick_score_trees_(options.quick_score_trees) {
    // The chance rate p0 is the map's occupied share around the matched map triangle (a dense
    // stand beside a sparse one: each tested at its own density), in kLevels steps.
    const double p1 = options.quick_check_true_rate;
    max_p0_ = 0.5 * p1;
    for (int k = 0; k < kLevels; ++k) {
      const double p0 = kMinP0 + (max_p0_ - kMinP0) * k / (kLevels - 1);
      hit_[k] = std::log(p1 / p0);
      miss_[k] = std::log((1 - p1) / (1 - p0));
    }
    accept_ = std::log(1 / options.quick_check_false_accept);
    reject_ = std::log(options.quick_check_false_reject);
  }

  // The query trees checked for poses from triangle `t`: the nearest query trees, nearest to
  // the triangle first (a triangle's pose is most accurate around it), without its vertices.
  void SetTriangle(const Triangle& t) {
    if (t.vertex == vertex_) return;  // the same triangle at another level
    vertex_ = t.vertex;
    const uint32_t n = static_cast<uint32_t>(std::min<size_t>(q_.xy.size(), kMaxChecks));
    const Eigen::Vector2d centroid =
        (q_.xy[t.vertex[0]] + q_.xy[t.vertex[1]] + q_.xy[t.vertex[2]]) / 3;
    by_distance_.clear();
    for (uint32_t i = 0; i < n; ++i) {
      if (i != t.vertex[0] && i != t.vertex[1] && i != t.vertex[2]) {
        by_distance_.push_back({static_cast<float>((q_.xy[i] - centroid).squaredNorm()), i});
      }
    }
    std::sort(by_distance_.begin(), by_distance_.end());
  }

  // Query trees among the quick_score_trees nearest the sensor that `pose` puts near a map tree.
  int Hits(const Rigid2& pose) const {
    const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
    int hits = 0;
    for (size_t i = 0; i < std::min<size_t>(q_.xy.size(), quick_score_trees_); ++i) {
      const Eigen::Vector2d& p = q_.xy[i];
      hits += m_.occupancy->Near(c * p.x() - s * p.y() + pose.translation.x(),
                                 s * p.x() + c * p.y() + pose.translation.y());
    }
    return hits;
  }

  // The pose maps p to (c p.x - s p.y + tx, s p.x + c p.y + ty); (x, y): where its map
  // triangle lies.
  bool Passes(float c, float s, float tx, float ty, float x, float y) const {
    const double p0 = std::clamp(m_.occupancy->OccupiedFractionAt(x, y), kMinP0, max_p0_);
    const int level =
        static_cast<int>(std::lround((p0 - kMinP0) / (max_p0_ - kMinP0) * (kLevels - 1)));
    const double hit = hit_[level], miss = miss_[level];
    double llr = 0;
    for (const auto& [d2, i] : by_distance_) {
      const Eigen::Vector2d& p = q_.xy[i];
      llr +=
          m_.occupancy->Near(c * p.x() - s * p.y() + tx, s * p.x() + c * p.y() + ty) ? hit : miss;
      if (llr >= accept_) return true;
      if (llr <= reject_) return false;
    }
    return false;
  }

 private:
  static constexpr size_t kMaxChecks = 40;
  const MapIndexImpl& m_;
  const LevelledQuery& q_;
  const size_t quick_score_trees_;
  std::vector<std::pair<float, uint32_t>> by_distance_;                    // the check order
  std::array<uint32_t, 3> vertex_ = {UINT32_MAX, UINT32_MAX, UINT32_MAX};  // ... for this triangle
  static constexpr int kLevels = 64;
  static constexpr double kMinP0 = 0.005;
  double max_p0_ = 0.375;
  double hit_[kLevels] = {}, miss_[kLevels] = {};
  double accept_ = 0, reject_ = 0;
};

// Pose cell for recognising a pose already found (0.5 m x 0.5 m x 1.5 deg).
uint64_t PoseCell(const Rigid2& pose) {
  const int64_t cx = static_cast<int64_t>(std::floor(pose.translation.x() / 0.5));
  const int64_t cy = static_cast<int64_t>(std::floor(pose.translation.y() / 0.5));
  const int64_t cyaw = static_cast<int64_t>(std::floor((pose.yaw + M_PI) / 0.026));
  return (static_cast<uint64_t>(cx & 0xFFFFFF) << 40) |
         (static_cast<uint64_t>(cy & 0xFFFFFF) << 16) | static_cast<uint64_t>(cyaw & 0xFFFF);
}

}  // namespace

void Polish(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
            Hypothesis* h) {
  const double gate = 1.5 * options.inlier_distance;
  const std::vector<Association> matches =
      Associate(m, q, h->pose, options, gate, options.quick_score_trees);
  if (matches.size() >= 3) {
    Rigid2Accumulator acc;
    for (const Association& a : matches) acc.Add(q.xy[a.query], m.Xy(a.map));
    h->pose = acc.Solve();
  }
  Score(m, q, options, h, options.inlier_distance, options.quick_score_trees);
}

std::vector<Association> Associate(const MapIndexImpl& m, const LevelledQuery& q,
                                   const Rigid2& pose, const RelocalizerOptions& options,
                                   double gate, size_t limit) {
  std::vector<Association> out;
  const double gate2 = gate * gate;
  for (uint32_t i = 0; i < std::min(limit, q.xy.size()); ++i) {
    const Eigen::Vector2d p = pose(q.xy[i]);
    auto [j, d2] = m.positions->Nearest({static_cast<float>(p.x()), static_cast<float>(p.y())});
    if (j < 0 || d2 > gate2) continue;
    const double query_dbh = q.dbh[i], map_dbh = m.trees[j].dbh;
    if (options.dbh_ratio_gate > 0 && query_dbh > 0 && map_dbh > 0 &&
        std::max(query_dbh, map_dbh) > options.dbh_ratio_gate * std::min(query_dbh, map_dbh)) {
      continue;  // not the same stem
    }
    out.push_back({i, static_cast<uint32_t>(j), std::sqrt(d2)});
  }
  return out;
}

void Score(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
           Hypothesis* h, double gate, size_t limit) {
  const std::vector<Association> inliers = Associate(m, q, h->pose, options, gate, limit);
  h->inliers = static_cast<int>(inliers.size());
  h->score = 0;
  double sum2 = 0;
  for (const Association& a : inliers) {
    const double r = a.distance / gate;
    h->score += 1.0 - r * r;
    sum2 += a.distance * a.distance;
  }
  h->rmse = inliers.empty() ? 0 : std::sqrt(sum2 / inliers.size());
}

void Refine(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
            Hypothesis* h) {
  for (double gate :
       {1.5 * options.inlier_distance, options.inlier_distance, options.inlier_distance,
        0.7 * options.inlier_distance, 0.7 * options.inlier_distance}) {
    const std::vector<Association> matches = Associate(m, q, h->pose, options, gate);
    if (matches.size() < 3) break;
    Rigid2Accumulator acc;
    for (const Association& a : matches) {
      const double r = a.distance / gate;
      acc.Add(q.xy[a.query], m.Xy(a.map), 1.0 - 0.5 * r * r);
    }
    h->pose = acc.Solve();
  }
  Score(m, q, options, h, options.inlier_distance);
}

int RatioTrees(const LevelledQuery& q, const RelocalizerOptions& options) {
  const int in_range =
      static_cast<int>(std::count_if(q.xy.begin(), q.xy.end(), [&](const Eigen::Vector2d& p) {
        return p.norm() <= options.ratio_range;
      }));
  return std::max(in_range, std::min<int>(q.xy.size(), options.min_ratio_trees));
}

int InliersAmongNearest(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                        int count, const RelocalizerOptions& options) {
  return static_cast<int>(Associate(m, q, pose, options, options.inlier_distance, count).size());
}

double ChanceInliers(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose) {
  double expected = 0;
  for (const Eigen::Vector2d& xy : q.xy) {
    const Eigen::Vector2d p = pose(xy);
    expected += m.occupancy->OccupiedFractionAt(p.x(), p.y());
  }
  return expected;
}

double PoissonTail(int k, double lambda) {
  if (k <= 0) return 1.0;
  if (!(lambda > 0)) return 0.0;
  double log_term = -lambda + k * std::log(lambda) - std::lgamma(k + 1.0);  // P(X = k)
  double sum = 0;
  for (int i = k; i < k + 2000; ++i) {
    const double term = std::exp(log_term);
    sum += term;
    if (i > lambda && term < 1e-16 * sum) break;
    log_term += std::log(lambda / (i + 1));
  }
  return std::min(1.0, sum);
}

namespace {

// One search: the query's triangles, looked up in passes of growing tolerance.
class Searcher {
 public:
  Searcher(const MapIndexImpl& m, const LevelledQuery& q, const std::optional<PriorPose>& prior,
           const Eigen::Vector2d& prior_xy, const RelocalizerOptions& options)
      : m_(m),
        q_(q),
        prior_(prior),
        prior_xy_(prior_xy),
        options_(options),
        seed_xy_(q.xy.begin(),
                 q.xy.begin() + std::min<size_t>(q.xy.size(), options.max_seed_trees)),
        check_(m, q, options),
        decisive_(
            std::max<int>(options.min_inliers,
                          std::ceil(options.decisive_fraction *
                                    std::min<size_t>(q.xy.size(), options.quick_score_trees)))),
        strong_(StrongInliers(q, options)),
        polish_hits_(std::max(3, static_cast<int>(kPolishShare * decisive_))) {
    triangles_ = QueryTriangles(seed_xy_, m, QuerySide(seed_xy_, m), options.triangle_tolerance);
    KeepSpread(triangles_, static_cast<size_t>(std::max(0, options.max_query_triangles)),
               kFirstTrianglesPerSeed, kMaxTrianglesPerSeed);
  }

  // Looks up at most `max_triangles` query triangles at `tolerance` (m), taking in turn the
  // nearest and the cheapest not yet taken: any triangle of true trees finds the pose; near
  // ones are the most reliable, cheap ones (rare shapes, the fewest map triangles in their key
  // box) cost least. Returns whether a decisive pose was found.
  bool Pass(float tolerance, size_t max_triangles) {
    std::vector<std::pair<double, size_t>> by_cost(triangles_.size());
    for (size_t i = 0; i < triangles_.size(); ++i) {
      // Cost per chance of finding the pose: the triangles scanned, over the share of the map
      // where a triangle of this band is indexed at all.
      const QueryTriangle& t = triangles_[i];
      const double share = std::max(kMinBandShare, m_.band_share[t.level]);
      by_cost[i] = {m_.tables[t.level]->CandidateCount(t.triangle.sides, tolerance) / share, i};
    }
    std::sort(by_cost.begin(), by_cost.end());
    std::vector<bool> taken(triangles_.size(), false);
    size_t nearest = 0, cheapest = 0;
    auto next = [&](size_t turn) -> size_t {
      size_t i;
      if (turn % 2 == 0) {
        while (taken[nearest]) ++nearest;
        i = nearest;
      } else {
        while (taken[by_cost[cheapest].second]) ++cheapest;
        i = by_cost[cheapest].second;
      }
      taken[i] = true;
      return i;
    };
    size_t stop = std::min(max_triangles, triangles_.size());
    bool decided = false;
    for (size_t turn = 0; turn < stop; ++turn) {
      const size_t before = result_.hypotheses.size();
      Lookup(triangles_[next(turn)], tolerance);
      // A pose that explains most nearby trees once refined decides the search, after a few
      // more triangles have had the chance to show a rival.
      if (!decided && Decisive(before)) {
        decided = true;
        stop = std::min(triangles_.size(), turn + 1 + options_.rival_triangles);
      }
      if (!decided && OverBudget()) break;
    }
    return decided;
  }

  bool Believable(const Hypothesis& refined) {
    const PoseBelief belief =
        Assess(m_, q_, refined, {result_.matches, SearchArea(m_, prior_)}, options_);
    result_.tested.emplace(refined.pose, belief.decoys);
    return belief.believable();
  }

  // Whether the search has scored so many hypotheses without a decisive one that more would
  // only find more of the same (a regular stand, matching everywhere): it ends there.
  bool OverBudget() {
    over_budget_ = over_budget_ || (options_.max_scored_hypotheses > 0 &&
                                    polished_ >= options_.max_scored_hypotheses);
    return over_budget_;
  }

  bool promising() const { return promising_; }

  PoseSearchResult Finish() {
    std::sort(result_.hypotheses.begin(), result_.hypotheses.end(),
              [](const Hypothesis& x, const Hypothesis& y) { return x.score > y.score; });
    return std::move(result_);
  }

 private:
  // Every map triangle matching `qt` within `tolerance` implies a pose; those that pass the
  // quick check and were not found before become hypotheses.
  void Lookup(const QueryTriangle& unit, float tolerance) {
    const Triangle& qt = unit.triangle;
    ++result_.triangles;
    const uint32_t a = qt.vertex[0], b = qt.vertex[1], c = qt.vertex[2];
    // The canonical labels come from sorted side lengths; where two sides are within the
    // tolerance, noise may have swapped them in the map, so the swapped labelling is tried too.
    TriangleFrame frames[3] = {FrameOf(seed_xy_[a], seed_xy_[b], seed_xy_[c])};
    int labellings = 1;
    if (qt.sides[1] - qt.sides[0] < tolerance) {
      frames[labellings++] = FrameOf(seed_xy_[b], seed_xy_[a], seed_xy_[c]);
    }
    if (qt.sides[2] - qt.sides[1] < tolerance) {
      frames[labellings++] = FrameOf(seed_xy_[a], seed_xy_[c], seed_xy_[b]);
    }
    const double prior_radius2 = prior_ ? prior_->radius * prior_->radius : 0.0;
    check_.SetTriangle(qt);
    m_.tables[unit.level]->ForEachMatch(qt.sides, tolerance, [&](const IndexedTriangle& t) {
      const TriangleFrame mt = t.frame();
      for (int l = 0; l < labellings; ++l) {
        const TriangleFrame& qf = frames[l];
        if (qf.turn * mt.turn < 0) continue;  // mirror image: no rigid motion maps it
        // map = R * query + t, with the long sides and the centroids aligned:
        // R = R(map heading) R(query heading)^T.
        const float cos_yaw = mt.cos_heading * qf.cos_heading + mt.sin_heading * qf.sin_heading;
        const float sin_yaw = mt.sin_heading * qf.cos_heading - mt.cos_heading * qf.sin_heading;
        const float tx = mt.cx - (cos_yaw * qf.cx - sin_yaw * qf.cy);
        const float ty = mt.cy - (sin_yaw * qf.cx + cos_yaw * qf.cy);
        if (prior_ && (Eigen::Vector2d(tx, ty) - prior_xy_).squaredNorm() > prior_radius2) {
          continue;
        }
        ++result_.matches;
        if (!check_.Passes(cos_yaw, sin_yaw, tx, ty, mt.cx, mt.cy)) continue;
        Hypothesis h;
        h.pose.yaw = std::atan2(sin_yaw, cos_yaw);
        h.pose.translation = {tx, ty};
        if (!found_cells_.insert(PoseCell(h.pose)).second) continue;  // found already
        result_.hypotheses.push_back(h);
      }
    });
  }

  // Polishes the hypotheses from `from` on; whether one of them is decisive.
  bool Decisive(size_t from) {
    bool decisive = false;
    for (size_t k = from; k < result_.hypotheses.size(); ++k) {
      Hypothesis& h = result_.hypotheses[k];
      // Only a pose that already puts a good share of the nearest trees near map trees can
      // become decisive: the others stay unscored (score 0) and cost one bitmap pass.
      if (check_.Hits(h.pose) < PolishHits(m_, q_, h.pose, polish_hits_, options_)) continue;
      ++polished_;
      Polish(m_, q_, options_, &h);
      promising_ = promising_ || h.inliers >= decisive_;
      if (decisive || h.inliers < decisive_ || h.score <= best_score_) continue;
      best_score_ = h.score;
      Hypothesis refined = h;
      Refine(m_, q_, options_, &refined);
      decisive = InliersAmongNearest(m_, q_, refined.pose, RatioTrees(q_, options_), options_) >=
                     strong_ &&
                 Believable(refined);
    }
    return decisive;
  }

  const MapIndexImpl& m_;
  const LevelledQuery& q_;
  const std::optional<PriorPose>& prior_;
  const Eigen::Vector2d prior_xy_;
  const RelocalizerOptions& options_;
  const std::vector<Eigen::Vector2d> seed_xy_;
  QuickCheck check_;
  const int decisive_;  // inliers among the nearest trees that make a pose worth refining
  const int strong_;    // inliers within ratio_range that decide the search (search_budget.h)
  // A hypothesis is polished and scored only with this many bitmap hits among the nearest
  // trees: this share of decisive_ (a triangle's pose can be a few degrees off before polish).
  static constexpr double kPolishShare = 0.4;
  static constexpr double kMinBandShare = 0.01;  // floor of a band's share in the cost order
  const int polish_hits_;
  int64_t polished_ = 0;    // hypotheses polished and scored
  bool promising_ = false;  // a polished hypothesis explained decisive_ of the nearest trees
  bool over_budget_ = false;
  std::vector<QueryTriangle> triangles_;
  double best_score_ = 0;
  std::unordered_set<uint64_t> found_cells_;
  PoseSearchResult result_;
};

}  // namespace

PoseSearchResult SearchPoses(const MapIndexImpl& m, const LevelledQuery& q,
                             const std::optional<PriorPose>& prior, const Eigen::Vector2d& prior_xy,
                             const RelocalizerOptions& options) {
  Searcher search(m, q, prior, prior_xy, options);
  // A first pass with a tight tolerance costs an eighth per triangle (the key box is a cube)
  // and finds most poses; the full tolerance follows only when it did not.
  const bool decided =
      options.first_pass_tolerance > 0 &&
      search.Pass(static_cast<float>(options.first_pass_tolerance), options.first_pass_triangles);
  // The full tolerance costs 8 times as much a triangle: all of them only when the first pass
  // saw a promising pose, else only the first few (a true pose found at the first pass's
  // tolerance needs a median of 10-20 triangles: a query with nothing after 200 is most likely
  // not in the map; its answer comes in about the time of a found one).
  if (!decided && !search.OverBudget()) {
    const bool all = search.promising() || options.first_pass_tolerance == 0;
    search.Pass(static_cast<float>(options.triangle_tolerance),
                all ? SIZE_MAX : static_cast<size_t>(options.unpromising_triangles));
  }
  return search.Finish();
}

}  // namespace forestmap::algorithms
