#pragma once
// Internal to the relocalizer: the levelled query, pose hypotheses and their scoring against the
// map, and the search that generates hypotheses from triangle matches.

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "algorithms/core/rigid2d.h"
#include "algorithms/relocalization/map_index_internal.h"
#include "algorithms/relocalization/relocalizer.h"

namespace forestmap::algorithms {

// The query after levelling, nearest trees first.
struct LevelledQuery {
  Eigen::Matrix3d level_from_sensor = Eigen::Matrix3d::Identity();
  std::vector<Eigen::Vector2d> xy;  // levelled horizontal positions (sensor at the origin)
  std::vector<double> z;            // levelled heights relative to the sensor
  std::vector<double> dbh;
  std::vector<uint32_t> used;  // indices into the request's trees
};

// A candidate pose of the levelled sensor in the map's kd coordinates.
struct Hypothesis {
  Rigid2 pose;  // kd coordinates from levelled sensor coordinates
  int inliers = 0;
  double score = 0;  // sum over inliers of (1 - (d / inlier_distance)^2)
  double rmse = 0;   // m
};

// A query tree and the map tree nearest to it under a pose.
struct Association {
  uint32_t query = 0;  // index into LevelledQuery
  uint32_t map = 0;    // index into the map's trees
  double distance = 0;
};

// Each of the `limit` nearest query trees whose nearest map tree is within `gate` (m), unless
// both DBH are known and differ by more than options.dbh_ratio_gate.
std::vector<Association> Associate(const MapIndexImpl& m, const LevelledQuery& q,
                                   const Rigid2& pose, const RelocalizerOptions& options,
                                   double gate, size_t limit = SIZE_MAX);

// Scores a pose on the `limit` nearest query trees (all by default), gate `gate` (m).
void Score(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
           Hypothesis* h, double gate, size_t limit = SIZE_MAX);

// The nearest query trees that hold `count` trees inside the map's coverage under `pose` (all
// of them when fewer lie inside): a pose is scored on its nearest trees inside the coverage, so
// a view at the edge of its map is scored on what the map shows of it.
size_t ScoringPrefix(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                     size_t count);

// One least-squares step on the nearest `limit` query trees (0: the ScoringPrefix of
// quick_score_trees; a triangle's pose can be a few degrees off), then the score on them.
void Polish(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
            Hypothesis* h, size_t limit = 0);

// ICP-style refinement: re-association with a shrinking gate, least squares in x, y, yaw.
void Refine(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options,
            Hypothesis* h);

// The nearest query trees an answer must explain a share of: those within
// options.ratio_range, at least the nearest options.min_ratio_trees (a drone high above a
// sparse forest sees its trees far away).
int RatioTrees(const LevelledQuery& q, const RelocalizerOptions& options);
// The query trees a pose puts inside the map's coverage (coverage.h): only those are evidence,
// for the pose or against it. The nearby ones among them are those an answer must explain a
// share of: the inside trees within options.ratio_range, at least the nearest
// options.min_ratio_trees inside trees.
struct ViewInCoverage {
  std::vector<uint8_t> inside;  // per query tree (LevelledQuery order)
  int nearby = 0;               // nearby trees inside the coverage
  int prefix = 0;               // the nearest `prefix` query trees hold every one of them
  double share = 0;             // of the RatioTrees nearest trees, the share inside
};
ViewInCoverage InCoverage(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                          const RelocalizerOptions& options);
// m, the range of the farthest of the RatioTrees nearest trees: how far beyond the coverage a
// pose may lie and still see into it.
double QueryReach(const LevelledQuery& q, const RelocalizerOptions& options);

// Inliers of `pose` among the `count` nearest query trees.
int InliersAmongNearest(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose,
                        int count, const RelocalizerOptions& options);

// Inliers a random pose would get here: the sum over query trees of the local chance of
// landing near a map tree (MapIndexImpl::ChanceAt: none outside the coverage).
double ChanceInliers(const MapIndexImpl& m, const LevelledQuery& q, const Rigid2& pose);

// P(X >= k) for X ~ Poisson(lambda).
double PoissonTail(int k, double lambda);

// The decoys of a pose (decoys.h): alternatives on the same local pattern.
struct DecoyTest {
  double gate = 0;        // m, inlier gate of the comparison (from the pose's own rmse)
  double pose_score = 0;  // the pose's score at that gate on the nearest trees
  Hypothesis best;        // the best decoy (score at that gate); score 0 when none
  // Share of the query trees a decoy puts within the occupancy radius of a map tree, at the
  // decoys' best heading (the chance level of a pose aligned to the local pattern).
  double pattern_rate = 0;
  // At that heading: the query trees the decoys put near a map tree (each decoy's anchor
  // excluded) and the query trees tried: the evidence behind pattern_rate.
  int pattern_hits = 0;
  int pattern_tries = 0;
  int candidates = 0;  // decoy poses tried
  bool passed = true;  // pose_score >= options.decoy_ratio x best decoy score
};

struct PoseSearchResult {
  std::vector<Hypothesis> hypotheses;  // scored on the nearest trees, best first
  // The last refined pose whose decoys the search tested, and the test (reused by the decision).
  std::optional<std::pair<Rigid2, DecoyTest>> tested;
  int triangles = 0;    // query triangles looked up
  int64_t matches = 0;  // triangle matches turned into poses
};

// Hypothesize and verify: every map triangle matching a query triangle (nearest first) implies
// a sensor pose; a sequential test on the nearest query trees against the map's occupancy grid
// rejects almost every wrong one after a handful of lookups; the survivors are scored. The
// search ends once a pose explains most nearby trees and a few more triangles found no rival,
// or when the query's triangles run out. With a prior, poses outside its radius are skipped.
// `other_search_area` (m^2): searched in other maps of the same question (RelocalizeQuery).
PoseSearchResult SearchPoses(const MapIndexImpl& m, const LevelledQuery& q,
                             const std::optional<PriorPose>& prior, const Eigen::Vector2d& prior_xy,
                             const RelocalizerOptions& options, double other_search_area = 0);

}  // namespace forestmap::algorithms
