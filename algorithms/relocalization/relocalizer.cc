#include "algorithms/relocalization/relocalizer.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "algorithms/core/leveling.h"
#include "algorithms/relocalization/decoys.h"
#include "algorithms/relocalization/heading_peaks.h"
#include "algorithms/relocalization/pose_covariance.h"
#include "algorithms/relocalization/pose_search.h"
#include "algorithms/relocalization/tilt_refinement.h"

namespace forestmap::algorithms {
namespace {

LevelledQuery Level(const RelocalizeQuery& query, const Eigen::Matrix3d& level_from_sensor,
                    const RelocalizerOptions& options) {
  LevelledQuery q;
  q.level_from_sensor = level_from_sensor;
  std::vector<std::pair<double, uint32_t>> by_range;
  for (uint32_t i = 0; i < query.trees.size(); ++i) {
    const Eigen::Vector3d p = q.level_from_sensor * query.trees[i].position;
    const double range = p.head<2>().norm();
    if (range <= options.max_query_range) by_range.push_back({range, i});
  }
  std::sort(by_range.begin(), by_range.end());
  for (auto [range, i] : by_range) {
    const Eigen::Vector3d p = q.level_from_sensor * query.trees[i].position;
    q.xy.push_back(p.head<2>());
    q.z.push_back(p.z());
    q.dbh.push_back(query.trees[i].dbh);
    q.used.push_back(i);
  }
  return q;
}

bool Distinct(const Rigid2& a, const Rigid2& b, const RelocalizerOptions& options) {
  return (a.translation - b.translation).norm() > options.distinct_distance ||
         std::abs(WrapAngle(a.yaw - b.yaw)) > options.distinct_yaw;
}

// The final pose in the map frame, with z from the matched trees.
RelocalizeResult Finish(const MapIndexImpl& m, const LevelledQuery& q, const Hypothesis& best,
                        const RelocalizerOptions& options) {
  RelocalizeResult result;
  PoseCovarianceInput uncertainty;
  uncertainty.yaw = best.pose.yaw;
  std::vector<double>& dz = uncertainty.dz;
  for (const Association& a : Associate(m, q, best.pose, options, options.inlier_distance)) {
    result.matches.push_back({static_cast<int>(q.used[a.query]), m.trees[a.map].id, a.distance});
    uncertainty.sensor_xy.push_back(q.xy[a.query]);
    uncertainty.residual.push_back(m.Xy(a.map) - best.pose(q.xy[a.query]));
    const double map_z = m.trees[a.map].position.z();
    if (IsKnown(map_z)) dz.push_back(map_z - q.z[a.query]);
  }
  result.covariance = PoseCovariance(uncertainty);
  double z = 0;  // a 2-D map has no heights: the pose is in its z = 0 plane
  if (!dz.empty()) {
    std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
    z = dz[dz.size() / 2];
  }
  const Eigen::Vector2d t = best.pose.translation + m.origin;
  result.map_from_sensor = PoseFromXyzYaw(t.x(), t.y(), z, best.pose.yaw);
  result.map_from_sensor.linear() = result.map_from_sensor.linear() * q.level_from_sensor;
  result.inliers = best.inliers;
  result.rmse = best.rmse;
  return result;
}

// With map heights, refines roll and pitch from the matched trees' heights (tilt_refinement.h),
// then the pose again in x, y, yaw; keeps the refinement only when it fits at least as well.
RelocalizeResult FinishWithTilt(const MapIndexImpl& m, const LevelledQuery& q,
                                const RelocalizeQuery& query, const Hypothesis& best,
                                const RelocalizerOptions& options) {
  std::vector<Eigen::Vector3d> levelled;
  std::vector<double> map_z;
  for (const Association& a : Associate(m, q, best.pose, options, options.inlier_distance)) {
    const double z = m.trees[a.map].position.z();
    if (!IsKnown(z)) continue;
    levelled.push_back({q.xy[a.query].x(), q.xy[a.query].y(), q.z[a.query]});
    map_z.push_back(z);
  }
  const std::optional<Eigen::Matrix3d> correction =
      options.refine_tilt ? RefineTilt(levelled, map_z, options.tilt) : std::nullopt;
  if (correction) {
    const LevelledQuery tilted = Level(query, *correction * q.level_from_sensor, options);
    Hypothesis refined = best;
    Refine(m, tilted, options, &refined);
    if (refined.inliers >= best.inliers && refined.rmse <= best.rmse) {
      return Finish(m, tilted, refined, options);
    }
  }
  return Finish(m, q, best, options);
}

// A levelled pose (kd coordinates) in the map frame, at the height of `like`.
Pose3 MapPose(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
              const Pose3& like) {
  const Eigen::Vector2d t = pose.translation + m.origin;
  Pose3 out = PoseFromXyzYaw(t.x(), t.y(), like.translation().z(), pose.yaw);
  out.linear() = out.linear() * q.level_from_sensor;
  return out;
}

// Whether `best` clearly beats `rival`: by the ambiguity ratio in score, or, when `best` fits
// tightly (a regular stand: the rival is the same grid shifted), at the tight gate.
bool BeatsRival(const MapIndexImpl& m, const LevelledQuery& q, const Hypothesis& best,
                const Hypothesis& rival, const PoseBelief& belief,
                const RelocalizerOptions& options) {
  if (best.score >= options.ambiguity_ratio * rival.score) return true;
  if (!belief.tight) return false;
  Hypothesis tight_best = best, tight_rival = rival;
  Score(m, q, options, &tight_best, belief.decoys.gate);
  Score(m, q, options, &tight_rival, belief.decoys.gate);
  return tight_best.score >= options.ambiguity_ratio * tight_rival.score;
}

void Ambiguous(const MapIndexImpl& m, const LevelledQuery& q, const Hypothesis& best,
               const Hypothesis& rival, const char* what, RelocalizeResult* result) {
  result->status = RelocalizeStatus::kAmbiguous;
  result->reason = RelocalizeReason::kAmbiguous;
  result->rival_map_from_sensor = MapPose(m, q, rival.pose, result->map_from_sensor);
  char detail[200];
  std::snprintf(detail, sizeof detail,
                "%s, %.1f m and %.0f deg apart, fit almost equally well (scores %.1f and %.1f)",
                what, (rival.pose.translation - best.pose.translation).norm(),
                std::abs(WrapAngle(rival.pose.yaw - best.pose.yaw)) * 180 / M_PI, best.score,
                rival.score);
  result->detail = detail;
}

double MinInlierRatio(const PoseBelief& belief, const RelocalizerOptions& options) {
  return belief.regular ? std::max(options.min_inlier_ratio, options.regular_min_inlier_ratio)
                        : options.min_inlier_ratio;
}

// Under the pose, too few query trees fall inside the map's coverage to tell a wrong pose from a
// view that shows little of the map, because others fall outside it (a small view wholly inside
// is judged as it is).
bool TooLittleInside(const ViewInCoverage& view, const RelocalizerOptions& options) {
  return view.nearby < options.min_ratio_trees &&
         std::find(view.inside.begin(), view.inside.end(), 0) != view.inside.end();
}

// Why `best` is no answer: too little of the view inside the map's coverage (the little that
// failed is all it can say), no better than chance, or too few of the nearby trees explained.
std::string NotFoundDetail(const Hypothesis& best, const ViewInCoverage& view, double ratio,
                           const PoseBelief& belief, const RelocalizerOptions& options) {
  char detail[256];
  if (TooLittleInside(view, options)) {
    std::snprintf(detail, sizeof detail,
                  "under the best pose only %d of the nearby trees (%.0f%%) fall inside what the "
                  "map covers, %d of them matched: too little of the view to judge (need %d)",
                  view.nearby, 100 * view.share, best.inliers, options.min_ratio_trees);
  } else if (!belief.significant) {
    std::snprintf(detail, sizeof detail,
                  "best pose matches %d trees within %.2f m (%.1f expected at random), %d of "
                  "the nearest %d: chance does as well somewhere among the %.2g poses searched; "
                  "is the drone in this map?",
                  belief.test.inliers, belief.test.gate, belief.test.chance,
                  belief.test.nearby_inliers, belief.test.nearby, belief.test.trials);
  } else {
    std::snprintf(detail, sizeof detail,
                  "best pose explains only %d trees (%.0f%% of the nearest %d trees); need %d "
                  "and %.0f%%",
                  best.inliers, 100 * ratio, view.nearby, options.min_inliers,
                  100 * MinInlierRatio(belief, options));
  }
  return detail;
}

// The answer for the best hypothesis, given the best distinct rival (none: null): LOCALIZED
// only when it is far above chance (a random forest's or the local pattern's), explains enough
// of the nearby trees and beats the rival and its decoys (decoys.h).
RelocalizeResult Decide(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizeQuery& query,
                        const Hypothesis& best, const Hypothesis* best_rival,
                        const SearchExtent& extent, const RelocalizerOptions& options,
                        const DecoyTest* decoys = nullptr) {
  const double rival = best_rival ? best_rival->score : 0.0;
  // Only the trees inside the map's coverage under the pose are evidence (coverage.h).
  const ViewInCoverage view = InCoverage(m, q, best.pose, options);
  const int nearest = view.nearby;
  const int nearest_inliers =
      nearest > 0 ? InliersAmongNearest(m, q, best.pose, view.prefix, options) : 0;
  const double ratio = nearest > 0 ? static_cast<double>(nearest_inliers) / nearest : 0.0;

  RelocalizeResult result = FinishWithTilt(m, q, query, best, options);
  result.confidence = best.score > 0 ? std::clamp(1.0 - rival / best.score, 0.0, 1.0) : 0.0;
  result.coverage_share = view.share;
  result.trees_in_coverage = view.nearby;
  const PoseBelief belief = Assess(m, q, best, extent, options, decoys);
  const bool too_few =
      best.inliers < options.min_inliers || ratio < MinInlierRatio(belief, options);
  if (!belief.significant || too_few) {
    result.status = RelocalizeStatus::kNotFound;
    if (TooLittleInside(view, options)) {
      result.reason = RelocalizeReason::kOutsideCoverage;
    } else {
      result.reason =
          belief.significant ? RelocalizeReason::kTooFewInliers : RelocalizeReason::kNotSignificant;
    }
    result.detail = NotFoundDetail(best, view, ratio, belief, options);
  } else if (best_rival && !BeatsRival(m, q, best, *best_rival, belief, options)) {
    Ambiguous(m, q, best, *best_rival, "two distinct poses", &result);
  } else if (!belief.decoys.passed) {
    Ambiguous(m, q, best, belief.decoys.best,
              "the query and a shifted or turned copy of it on the same regular pattern", &result);
  } else {
    result.status = RelocalizeStatus::kLocalized;
    result.reason = RelocalizeReason::kNone;
    char detail[256];
    std::snprintf(
        detail, sizeof detail,
        "%d trees matched (%.0f%% of the nearest %d trees, %.1f expected by chance; "
        "%d within %.2f m, log likelihood ratio %.0f over %.2g poses), next distinct pose "
        "scores %.1f",
        best.inliers, 100 * ratio, nearest, belief.chance, belief.test.inliers, belief.test.gate,
        belief.test.log_ratio, belief.test.trials, rival);
    result.detail = detail;
  }
  if (result.status != RelocalizeStatus::kLocalized) {
    result.map_from_sensor = Pose3::Identity();
    result.covariance.setZero();
  }
  return result;
}

RelocalizeResult TooFewTrees(const RelocalizeQuery& query, const MapIndexImpl& m) {
  RelocalizeResult result;
  result.reason = RelocalizeReason::kTooFewTrees;
  result.detail = "need at least 3 query trees and 3 map trees; the query has " +
                  std::to_string(query.trees.size()) + ", the map " +
                  std::to_string(m.trees.size());
  return result;
}

}  // namespace

void RelocalizerOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("RelocalizerOptions: ") + what);
  };
  require(max_query_range > 0, "max_query_range must be > 0");
  require(inlier_distance > 0, "inlier_distance must be > 0");
  require(triangle_tolerance > 0, "triangle_tolerance must be > 0");
  require(min_inliers >= 3, "min_inliers must be >= 3");
  require(min_inlier_ratio >= 0 && min_inlier_ratio <= 1 && regular_min_inlier_ratio >= 0 &&
              regular_min_inlier_ratio <= 1,
          "min_inlier_ratio and regular_min_inlier_ratio must be in [0, 1]");
  require(min_ratio_trees >= 1, "min_ratio_trees must be >= 1");
  require(dbh_ratio_gate == 0 || dbh_ratio_gate >= 1, "dbh_ratio_gate must be 0 (off) or >= 1");
  require(ambiguity_ratio >= 1 && decoy_ratio >= 1, "ambiguity_ratio, decoy_ratio must be >= 1");
  require(chance_sigmas >= 0, "chance_sigmas must be >= 0");
  require(false_alarm > 0 && false_alarm <= 1, "false_alarm must be in (0, 1]");
  require(distinct_distance > 0 && distinct_yaw > 0, "distinct_distance/yaw must be > 0");
  require(max_seed_trees >= 3, "max_seed_trees must be >= 3");
  require(refine_score_fraction >= 0 && refine_score_fraction <= 1,
          "refine_score_fraction must be in [0, 1]");
  require(refine_hypotheses >= 1 && quick_score_trees >= 3,
          "refine_hypotheses must be >= 1 and quick_score_trees >= 3");
  require(first_pass_tolerance >= 0 && first_pass_tolerance <= triangle_tolerance &&
              first_pass_triangles >= 0 && unpromising_triangles >= 0,
          "first pass: need 0 <= first_pass_tolerance <= triangle_tolerance, triangles >= 0");
  require(max_query_triangles >= 1 && rival_triangles >= 0,
          "max_query_triangles must be >= 1 and rival_triangles >= 0");
  require(quick_check_true_rate > 0 && quick_check_true_rate < 1 && quick_check_false_accept > 0 &&
              quick_check_false_accept < 1 && quick_check_false_reject > 0 &&
              quick_check_false_reject < 1,
          "quick check rates must be in (0, 1)");
  tilt.Check();
  leveling.Check();
  require(decisive_fraction > 0 && decisive_fraction <= 1, "decisive_fraction must be in (0, 1]");
}

const char* ToString(RelocalizeReason reason) {
  switch (reason) {
    case RelocalizeReason::kNone:
      return "none";
    case RelocalizeReason::kTooFewTrees:
      return "too_few_trees";
    case RelocalizeReason::kNoMatchingConstellation:
      return "no_matching_constellation";
    case RelocalizeReason::kNotSignificant:
      return "not_significant";
    case RelocalizeReason::kTooFewInliers:
      return "too_few_inliers";
    case RelocalizeReason::kAmbiguous:
      return "ambiguous";
    case RelocalizeReason::kOutsidePrior:
      return "outside_prior";
    case RelocalizeReason::kOutsideCoverage:
      return "outside_coverage";
  }
  return "unknown";
}

// A prior search that found nothing: does the map hold the query elsewhere? Then the answer's
// reason is kOutsidePrior (a second, global search: only on this path).
static RelocalizeResult ExplainPriorMiss(const MapIndex& index, const RelocalizeQuery& query,
                                         const RelocalizerOptions& options,
                                         RelocalizeResult result) {
  RelocalizeQuery global = query;
  global.prior.reset();
  const RelocalizeResult elsewhere = Relocalize(index, global, options);
  if (elsewhere.status != RelocalizeStatus::kLocalized) return result;
  const double distance = (elsewhere.map_from_sensor.translation().head<2>() -
                           query.prior->map_from_sensor.translation().head<2>())
                              .norm();
  if (distance <= query.prior->radius) return result;
  char detail[160];
  std::snprintf(detail, sizeof detail,
                "no pose within %.1f m of the prior; the trees match the map %.1f m from it",
                query.prior->radius, distance);
  result.reason = RelocalizeReason::kOutsidePrior;
  result.detail = detail;
  return result;
}

const char* ToString(RelocalizeStatus status) {
  switch (status) {
    case RelocalizeStatus::kLocalized:
      return "localized";
    case RelocalizeStatus::kAmbiguous:
      return "ambiguous";
    case RelocalizeStatus::kNotFound:
      return "not_found";
  }
  return "unknown";
}

RelocalizeResult Relocalize(const MapIndex& index, const RelocalizeQuery& query,
                            const RelocalizerOptions& options) {
  options.Check();
  const MapIndexImpl& m = index.impl();
  RelocalizeResult result;
  if (query.trees.size() < 3 || m.trees.size() < 3) return TooFewTrees(query, m);
  const LevelledQuery q = Level(
      query, LevelSensor(query.trees, query.gravity, options.leveling).level_from_sensor, options);
  Eigen::Vector2d prior_xy = Eigen::Vector2d::Zero();
  if (query.prior) prior_xy = query.prior->map_from_sensor.translation().head<2>() - m.origin;

  const PoseSearchResult search =
      SearchPoses(m, q, query.prior, prior_xy, options, query.other_search_area);
  const int verified = static_cast<int>(search.hypotheses.size());
  result.triangles = search.triangles;
  result.poses_checked = search.matches;
  if (search.hypotheses.empty()) {
    result.reason = RelocalizeReason::kNoMatchingConstellation;
    result.detail = "no constellation of the query's trees matches the map";
    return query.prior ? ExplainPriorMiss(index, query, options, std::move(result)) : result;
  }
  // Refine the best few distinct hypotheses (best first by their score on the nearest trees);
  // only these take part in the decision below.
  std::vector<Hypothesis> hypotheses;
  for (const Hypothesis& h : search.hypotheses) {
    if (h.score < options.refine_score_fraction * search.hypotheses.front().score) break;
    if (std::all_of(hypotheses.begin(), hypotheses.end(),
                    [&](const Hypothesis& p) { return Distinct(h.pose, p.pose, options); })) {
      hypotheses.push_back(h);
    }
    if (hypotheses.size() == static_cast<size_t>(options.refine_hypotheses)) break;
  }
  for (Hypothesis& h : hypotheses) Refine(m, q, options, &h);
  std::sort(hypotheses.begin(), hypotheses.end(),
            [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });

  const Hypothesis& best = hypotheses.front();
  const Hypothesis* rival = nullptr;
  for (const Hypothesis& h : hypotheses) {
    if (Distinct(h.pose, best.pose, options) && (!rival || h.score > rival->score)) rival = &h;
  }
  const bool tested = search.tested && search.tested->first.yaw == best.pose.yaw &&
                      search.tested->first.translation == best.pose.translation;
  result = Decide(m, q, query, best, rival,
                  {search.matches,
                   SearchArea(m, query.prior, QueryReach(q, options)) + query.other_search_area},
                  options, tested ? &search.tested->second : nullptr);
  result.hypotheses = verified;
  result.triangles = search.triangles;
  result.poses_checked = search.matches;
  if (query.prior && result.status == RelocalizeStatus::kNotFound) {
    return ExplainPriorMiss(index, query, options, std::move(result));
  }
  return result;
}

double QuerySearchArea(const MapIndex& index, const RelocalizeQuery& query,
                       const RelocalizerOptions& options) {
  options.Check();
  const LevelledQuery q = Level(
      query, LevelSensor(query.trees, query.gravity, options.leveling).level_from_sensor, options);
  return SearchArea(index.impl(), query.prior, QueryReach(q, options));
}

RelocalizeResult RefineNear(const MapIndex& index, const RelocalizeQuery& query,
                            const Pose3& map_from_sensor_guess, double yaw_window,
                            const RelocalizerOptions& options) {
  options.Check();
  const MapIndexImpl& m = index.impl();
  if (query.trees.size() < 3 || m.trees.size() < 3) return TooFewTrees(query, m);
  const LevelledQuery q = Level(
      query, LevelSensor(query.trees, query.gravity, options.leveling).level_from_sensor, options);
  // The guess's heading in the levelled frame (its tilt is replaced by this frame's levelling).
  const double guess_yaw = YawOf(map_from_sensor_guess.linear() * q.level_from_sensor.transpose());
  const Eigen::Vector2d guess_xy = map_from_sensor_guess.translation().head<2>() - m.origin;
  // Headings tried: across the window around the guess (headings wobble more than positions
  // between frames), and the strongest bearing alignments (a turn the guess missed).
  constexpr double kYawStep = 0.05;  // rad
  std::vector<double> headings;
  const int steps = static_cast<int>(std::ceil(yaw_window / kYawStep));
  for (int k = -steps; k <= steps; ++k) headings.push_back(WrapAngle(guess_yaw + k * kYawStep));
  for (double yaw : HeadingPeaks(m, q, guess_xy, /*count=*/3)) headings.push_back(yaw);

  const double shift = options.inlier_distance;  // m, position seeds around the guess
  std::vector<Hypothesis> seeds;
  for (double yaw : headings) {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        Hypothesis h;
        h.pose.yaw = yaw;
        h.pose.translation = guess_xy + shift * Eigen::Vector2d(dx, dy);
        Score(m, q, options, &h, 1.5 * options.inlier_distance,
              ScoringPrefix(m, q, h.pose, options.quick_score_trees));
        seeds.push_back(h);
      }
    }
  }
  auto by_score = [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; };
  std::sort(seeds.begin(), seeds.end(), by_score);
  const int64_t seeds_tried = static_cast<int64_t>(seeds.size());
  seeds.resize(std::min<size_t>(seeds.size(), 3));
  for (Hypothesis& h : seeds) Refine(m, q, options, &h);
  std::sort(seeds.begin(), seeds.end(), by_score);
  RelocalizeResult result =
      Decide(m, q, query, seeds.front(), /*best_rival=*/nullptr, {seeds_tried, 0.0}, options);
  result.hypotheses = static_cast<int>(seeds.size());
  return result;
}

}  // namespace forestmap::algorithms
