#include "algorithms/relocalization/pose_search.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "algorithms/relocalization/decoys.h"
#include "algorithms/relocalization/query_triangles.h"
#include "algorithms/relocalization/quick_check.h"
#include "algorithms/relocalization/search_budget.h"
#include "algorithms/relocalization/significance.h"

namespace forestmap::algorithms {
namespace {

// Pose cell for recognising a pose already found (0.5 m x 0.5 m x 1.5 deg).
uint64_t PoseCell(const Rigid2& pose) {
  const int64_t cx = static_cast<int64_t>(std::floor(pose.translation.x() / 0.5));
  const int64_t cy = static_cast<int64_t>(std::floor(pose.translation.y() / 0.5));
  const int64_t cyaw = static_cast<int64_t>(std::floor((pose.yaw + M_PI) / 0.026));
  return (static_cast<uint64_t>(cx & 0xFFFFFF) << 40) |
         (static_cast<uint64_t>(cy & 0xFFFFFF) << 16) | static_cast<uint64_t>(cyaw & 0xFFFF);
}

}  // namespace

size_t ScoringPrefix(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                     size_t count) {
  const size_t n = std::min(q.xy.size(), count);
  if (n == 0 || (q.xy[n - 1].norm() <= m.coverage->deep_reach() &&
                 m.coverage->Deep(pose.translation.x(), pose.translation.y()))) {
    return n;  // deep inside: every one of the nearest trees is
  }
  size_t prefix = 0, inside = 0;
  for (; prefix < q.xy.size() && inside < count; ++prefix) inside += m.Covered(pose(q.xy[prefix]));
  return prefix;
}

void Polish(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
            Hypothesis* h, size_t limit) {
  if (limit == 0) limit = ScoringPrefix(m, q, h->pose, options.quick_score_trees);
  const double gate = 1.5 * options.inlier_distance;
  const std::vector<Association> matches = Associate(m, q, h->pose, options, gate, limit);
  if (matches.size() >= 3) {
    Rigid2Accumulator acc;
    for (const Association& a : matches) acc.Add(q.xy[a.query], m.Xy(a.map));
    h->pose = acc.Solve();
  }
  Score(m, q, options, h, options.inlier_distance, limit);
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

ViewInCoverage InCoverage(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                          const RelocalizerOptions& options) {
  ViewInCoverage view;
  view.inside.resize(q.xy.size());
  int inside = 0;
  for (size_t i = 0; i < q.xy.size(); ++i) {
    view.inside[i] = m.Covered(pose(q.xy[i]));
    if (!view.inside[i]) continue;
    ++inside;
    if (q.xy[i].norm() <= options.ratio_range || view.nearby < options.min_ratio_trees) {
      ++view.nearby;
      view.prefix = static_cast<int>(i) + 1;
    }
  }
  const int nearest = RatioTrees(q, options);
  int nearest_inside = 0;
  for (int i = 0; i < nearest; ++i) nearest_inside += view.inside[i];
  view.share = nearest > 0 ? static_cast<double>(nearest_inside) / nearest : 0.0;
  return view;
}

double QueryReach(const LevelledQuery& q, const RelocalizerOptions& options) {
  const int nearest = RatioTrees(q, options);
  return nearest > 0 ? q.xy[nearest - 1].norm() : 0.0;
}

int InliersAmongNearest(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                        int count, const RelocalizerOptions& options) {
  return static_cast<int>(Associate(m, q, pose, options, options.inlier_distance, count).size());
}

double ChanceInliers(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose) {
  double expected = 0;
  for (const Eigen::Vector2d& xy : q.xy) expected += m.ChanceAt(pose(xy));
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

// Outer seeds (SearchPoses): kMinOuterCentres to kMaxOuterCentres centres, each searched over
// at least kMinOuterTriangles triangles.
constexpr int kMinOuterCentres = 3, kMaxOuterCentres = 8;
constexpr size_t kMinOuterTriangles = 20;

// One search: the query's triangles, looked up in passes of growing tolerance.
class Searcher {
 public:
  Searcher(const MapIndexImpl& m, const LevelledQuery& q, const std::optional<PriorPose>& prior,
           const Eigen::Vector2d& prior_xy, const RelocalizerOptions& options,
           double other_search_area)
      : m_(m),
        q_(q),
        prior_(prior),
        prior_xy_(prior_xy),
        options_(options),
        check_(m, q, options),
        reach_(QueryReach(q, options)),
        other_search_area_(other_search_area) {}

  // The seeds whose triangles the next passes look up: query trees (indices), nearest to where
  // they are taken from first.
  // `budget`: the hypotheses they may score without a decisive one (0: no limit).
  void Seed(std::vector<uint32_t> pool, int64_t budget) {
    budget_ = budget;
    polished_ = 0;
    over_budget_ = false;
    pool_ = std::move(pool);
    seed_xy_.clear();
    for (uint32_t i : pool_) seed_xy_.push_back(q_.xy[i]);
    check_.SetPool(pool_);
    triangles_ = QueryTriangles(seed_xy_, m_, QuerySide(seed_xy_, m_), options_.triangle_tolerance);
    KeepSpread(triangles_, static_cast<size_t>(std::max(0, options_.max_query_triangles)),
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
        Assess(m_, q_, refined,
               {result_.matches, SearchArea(m_, prior_, reach_) + other_search_area_}, options_);
    result_.tested.emplace(refined.pose, belief.decoys);
    return belief.believable();
  }

  // Whether the search has scored so many hypotheses without a decisive one that more would
  // only find more of the same (a regular stand, matching everywhere): it ends there.
  bool OverBudget() {
    over_budget_ = over_budget_ || (budget_ > 0 && polished_ >= budget_);
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
      // Only a pose that already puts a good share of the nearest trees inside the coverage
      // near map trees can become decisive: the others stay unscored (score 0) and cost one
      // bitmap pass.
      const QuickCheck::Scored near = check_.Hits(h.pose);
      const int decisive_inliers = DecisiveInliers(near.inside);
      const int base = std::max(3, static_cast<int>(kPolishShare * decisive_inliers));
      if (near.hits < PolishHits(m_, q_, h.pose, base, options_, near.inside)) continue;
      ++polished_;
      Polish(m_, q_, options_, &h, near.prefix);
      promising_ = promising_ || h.inliers >= decisive_inliers;
      if (decisive || h.inliers < decisive_inliers || h.score <= best_score_) continue;
      best_score_ = h.score;
      Hypothesis refined = h;
      Refine(m_, q_, options_, &refined);
      const ViewInCoverage view = InCoverage(m_, q_, refined.pose, options_);
      decisive = InliersAmongNearest(m_, q_, refined.pose, view.prefix, options_) >=
                     StrongInliers(view.nearby, options_) &&
                 Believable(refined);
    }
    return decisive;
  }

  // Inliers among the nearest quick_score_trees that make a pose worth refining, when
  // `inside` of them lie inside the coverage under it.
  int DecisiveInliers(int inside) const {
    return std::max<int>(options_.min_inliers, std::ceil(options_.decisive_fraction * inside));
  }

  const MapIndexImpl& m_;
  const LevelledQuery& q_;
  const std::optional<PriorPose>& prior_;
  const Eigen::Vector2d prior_xy_;
  const RelocalizerOptions& options_;
  std::vector<uint32_t> pool_;            // the seeds (Seed) ...
  std::vector<Eigen::Vector2d> seed_xy_;  // ... and their positions
  QuickCheck check_;
  const double reach_;  // m, QueryReach: how far beyond the coverage a pose may see into it
  const double other_search_area_;  // m^2, searched in the question's other maps
  // A hypothesis is polished and scored only with this many bitmap hits among the nearest
  // trees: this share of DecisiveInliers (a triangle's pose can be a few degrees off before
  // polish).
  static constexpr double kPolishShare = 0.4;
  static constexpr double kMinBandShare = 0.01;  // floor of a band's share in the cost order
  int64_t polished_ = 0;                         // hypotheses polished and scored ...
  int64_t budget_ = 0;                           // ... at most, with these seeds
  bool promising_ = false;  // a polished hypothesis reached its DecisiveInliers
  bool over_budget_ = false;
  std::vector<QueryTriangle> triangles_;
  double best_score_ = 0;
  std::unordered_set<uint64_t> found_cells_;
  PoseSearchResult result_;
};

// The `count` query trees nearest `centre` (levelled sensor frame), nearest first.
std::vector<uint32_t> SeedsAround(const LevelledQuery& q, const Eigen::Vector2d& centre,
                                  size_t count) {
  std::vector<std::pair<double, uint32_t>> by_distance;
  for (uint32_t i = 0; i < q.xy.size(); ++i) {
    by_distance.push_back({(q.xy[i] - centre).squaredNorm(), i});
  }
  count = std::min(count, by_distance.size());
  std::partial_sort(by_distance.begin(), by_distance.begin() + count, by_distance.end());
  std::vector<uint32_t> seeds(count);
  for (size_t k = 0; k < count; ++k) seeds[k] = by_distance[k].second;
  return seeds;
}

// Where a view takes seeds on every side in turn: points on a circle halfway between its seeds'
// reach and the view's, about a seed disc apart (none when its seeds reach as far as it).
std::vector<Eigen::Vector2d> OuterSeedCentres(const LevelledQuery& q,
                                              const RelocalizerOptions& options) {
  const size_t seeds = static_cast<size_t>(options.max_seed_trees);
  if (q.xy.size() <= seeds) return {};
  const double inner = q.xy[seeds - 1].norm(), reach = QueryReach(q, options);
  if (!(inner > 0 && inner < reach)) return {};
  const double radius = 0.5 * (inner + reach);
  const int count = std::clamp(static_cast<int>(std::ceil(M_PI * radius / inner)), kMinOuterCentres,
                               kMaxOuterCentres);
  std::vector<Eigen::Vector2d> centres;
  for (int k = 0; k < count; ++k) {
    const double bearing = 2 * M_PI * k / count;
    centres.push_back(radius * Eigen::Vector2d(std::cos(bearing), std::sin(bearing)));
  }
  return centres;
}

}  // namespace

PoseSearchResult SearchPoses(const MapIndexImpl& m, const LevelledQuery& q,
                             const std::optional<PriorPose>& prior, const Eigen::Vector2d& prior_xy,
                             const RelocalizerOptions& options, double other_search_area) {
  Searcher search(m, q, prior, prior_xy, options, other_search_area);
  search.Seed(SeedsAround(q, Eigen::Vector2d::Zero(), options.max_seed_trees),
              options.max_scored_hypotheses);
  // A first pass with a tight tolerance costs an eighth per triangle (the key box is a cube)
  // and finds most poses; the full tolerance follows only when it did not.
  bool decided =
      options.first_pass_tolerance > 0 &&
      search.Pass(static_cast<float>(options.first_pass_tolerance), options.first_pass_triangles);
  // The full tolerance costs 8 times as much a triangle: all of them only when the first pass
  // saw a promising pose, else only the first few (a true pose found at the first pass's
  // tolerance needs a median of 10-20 triangles: a query with nothing after 200 is most likely
  // not in the map; its answer comes in about the time of a found one).
  if (!decided && !search.OverBudget()) {
    const bool all = search.promising() || options.first_pass_tolerance == 0;
    decided = search.Pass(static_cast<float>(options.triangle_tolerance),
                          all ? SIZE_MAX : static_cast<size_t>(options.unpromising_triangles));
  }
  // The seeds lie nearest the sensor, and so do the first triangles; at the edge of its map
  // they may all be trees the map does not hold (a dense stand's forty nearest trees lie within
  // a few metres). Seeds around points farther out on every side in turn, then, with the first
  // pass's budget shared among them.
  const std::vector<Eigen::Vector2d> centres = OuterSeedCentres(q, options);
  const double tolerance =
      options.first_pass_tolerance > 0 ? options.first_pass_tolerance : options.triangle_tolerance;
  for (size_t k = 0; k < centres.size() && !decided; ++k) {
    search.Seed(SeedsAround(q, centres[k], options.max_seed_trees),
                options.max_scored_hypotheses / static_cast<int64_t>(centres.size()));
    decided = search.Pass(
        static_cast<float>(tolerance),
        std::max<size_t>(kMinOuterTriangles, options.first_pass_triangles / centres.size()));
  }
  return search.Finish();
}

}  // namespace forestmap::algorithms
