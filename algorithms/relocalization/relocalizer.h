#pragma once
// Global and prior-bounded relocalization of a sensor in a tree map.
//
// Method (after Zmeškalová 2023, sec. 5.7-5.9: tree constellations, RANSAC-style pair
// matching, ICP; made robust to misses and false stems): the query is levelled (gravity, else the
// mean stem axis, else level); triangles of nearby query trees are looked up by their side
// lengths in the map's triangle table (map_index.h); every match implies a sensor pose (x, y,
// yaw), which a sequential test against the map's occupancy grid accepts or rejects after a few
// lookups (pose_search.h); the survivors are scored on the nearest trees, the best distinct ones
// refined by ICP-style re-association with least squares in x, y, yaw (z from the matched
// trees). The answer is LOCALIZED only when the best pose is far above chance and beats every
// distinct alternative by a clear margin. A prior bounds the search to a radius around its
// position; its heading is not used (odometry yaw drifts).

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/leveling.h"
#include "algorithms/relocalization/map_index.h"
#include "algorithms/relocalization/tilt_refinement.h"

namespace forestmap::algorithms {

struct PriorPose {
  Pose3 map_from_sensor = Pose3::Identity();
  double radius = 10.0;  // m, the sensor is within this distance of the prior position
};

struct RelocalizeQuery {
  std::vector<DetectedTree> trees;         // sensor frame
  std::optional<Eigen::Vector3d> gravity;  // gravity (down) in the sensor frame
  std::optional<PriorPose> prior;
  // m^2 searched in the other maps of the same question (one question over many maps): counts
  // in this map's look-elsewhere test (significance.h) beside its own search area. 0: one map.
  double other_search_area = 0;
};

struct RelocalizerOptions {
  // m, query trees farther (horizontally) are not used. A drone high up sees trunks only far
  // away (its lower beams reach breast height beyond 30 m): at 40 m, 2 of 200 simulated OS1-64
  // scans of the longleaf map were lost; the real sequences detect trees up to ~55 m.
  double max_query_range = 60.0;
  int max_seed_trees = 40;           // nearest query trees whose triangles seed hypotheses
  int max_query_triangles = 200;     // at most this many query triangles (nearest first)
  double triangle_tolerance = 0.20;  // m, per-side length tolerance of triangle matches
  // A first pass over this many triangles with a tighter tolerance (0 = none): an eighth of
  // the matches per triangle, and enough for most queries.
  double first_pass_tolerance = 0.10;  // m
  int first_pass_triangles = 200;
  // The full tolerance's pass looks up at most this many triangles when the first pass found no
  // pose explaining decisive_fraction of the nearest trees (fast proof of absence). At 50 a
  // foreign view's NOT_FOUND costs a third less, but real frames with noisy detections are lost
  // (Oxford_Stein: 1 of 1,046).
  int unpromising_triangles = 100;
  // Quick check of each triangle match's pose (a sequential test on the nearest query trees):
  // share of them a true pose puts on map trees, and the accepted error rates.
  double quick_check_true_rate = 0.75;
  double quick_check_false_accept = 1e-4;  // wrong poses that pass on to scoring
  double quick_check_false_reject = 0.01;  // true poses rejected (other triangles find them)
  // Decisive: a pose explaining this share of the quick_score_trees nearest trees ends the
  // search after rival_triangles more query triangles.
  double decisive_fraction = 0.6;
  int rival_triangles = 4;
  // The search ends after scoring this many hypotheses without a decisive one (0 = no limit): a
  // regular stand matches almost everywhere, and further matches are more of the same.
  int max_scored_hypotheses = 400;
  // Refine roll/pitch from the matched trees' map heights (tilt_refinement.h). Off by default:
  // it helps steeply tilted sensors (Stein: median error 0.096 -> 0.086 m) but costs ~1 pp
  // strict recall where map heights are noisy (Venman).
  bool refine_tilt = false;
  TiltRefinementOptions tilt;
  LevelingOptions leveling;            // roll and pitch from stem axes when no gravity is given
  int quick_score_trees = 30;          // hypotheses are ranked on this many nearest query trees
  int refine_hypotheses = 8;           // best distinct hypotheses refined by ICP
  double refine_score_fraction = 0.3;  // ... if they score at least this share of the best
  double inlier_distance = 0.4;        // m, a query tree within this of a map tree is an inlier
  // ... unless both DBH are known and differ by more than this factor (0 = DBH not used). Real
  // detections are noisy: 10% of true matches differ by 1.8x (Stein) to 2.4x (Venman).
  double dbh_ratio_gate = 3.0;
  int min_inliers = 6;            // fewer inliers -> NOT_FOUND
  double ratio_range = 20.0;      // m, query trees within this range count for the ratio
  double min_inlier_ratio = 0.2;  // inliers / query trees within ratio_range; less -> NOT_FOUND
  int min_ratio_trees = 10;       // ... counting at least this many nearest query trees
  // ... and at least this share where the stand is regular (decoys.h): a grid shifted by a
  // spacing explains a third of a query (foreign plantations: 27-40%), the true pose most of it
  // (correct answers on the real sequences and simulated views: 58% and more).
  double regular_min_inlier_ratio = 0.45;
  // Inliers must exceed chance by this many Poisson sigmas. Above 5: refinement lifts the best
  // of many wrong poses over the Poisson expectation (Wild_V02 frames in the Stein map reach
  // 5.3 sigma, true answers on the real sequences 6.6 and more).
  double chance_sigmas = 6.0;
  // ... and the best of all the poses tried must reach them by chance with at most this
  // probability (Poisson tail times the number of poses: what decides in sparse maps), and the
  // likelihood ratio of its nearby trees must beat every pose cell searched at this
  // probability (significance.h). A wrong pose is worse than none: at 1% a view of six trees
  // from a sparse stand (paracou) found itself in a small dense map (boreasSA) once in 16,200
  // foreign views; at 0.1% none did, and sparse views need about one tree more.
  double false_alarm = 0.001;
  double ambiguity_ratio = 1.5;  // best score must be >= this x the best distinct pose
  // ... and >= this x its best decoy (the query shifted or turned onto the same local pattern,
  // decoys.h), both scored at a gate from the pose's own residuals: regular stands.
  double decoy_ratio = 1.5;
  double distinct_distance = 2.0;  // m, poses farther apart than this are distinct
  double distinct_yaw = 0.17;      // rad (~10 deg), or whose yaws differ more than this
  void Check() const;
};

enum class RelocalizeStatus { kLocalized, kAmbiguous, kNotFound };

// Why an answer is what it is (beside the human-readable detail).
enum class RelocalizeReason {
  kNone,                     // LOCALIZED
  kTooFewTrees,              // fewer than 3 query trees (or map trees): nothing to match
  kNoMatchingConstellation,  // no triangle of the query's trees matches the map
  kNotSignificant,           // the best pose is no better than chance here
  kTooFewInliers,            // the best pose explains too few of the nearby trees
  kAmbiguous,                // a distinct rival pose (rival_map_from_sensor) fits about as well
  kOutsidePrior,             // nothing within the prior's radius; the map matches elsewhere
  // NOT_FOUND: under the best pose too few query trees (fewer than min_ratio_trees) fall inside
  // the map's coverage, the others outside it, to tell a wrong pose from a view that shows little
  // of the map.
  kOutsideCoverage,
};

struct TreeMatch {
  int query_index = 0;
  int64_t map_tree_id = 0;
  double distance = 0;  // m, horizontal, under the final pose
};

struct RelocalizeResult {
  RelocalizeStatus status = RelocalizeStatus::kNotFound;
  Pose3 map_from_sensor = Pose3::Identity();  // meaningful when kLocalized
  int inliers = 0;
  std::vector<TreeMatch> matches;
  double rmse = 0;        // m, horizontal RMS of the matches
  double confidence = 0;  // [0, 1]
  std::string detail;     // why ambiguous / not found, for humans
  RelocalizeReason reason = RelocalizeReason::kTooFewTrees;
  std::optional<Pose3> rival_map_from_sensor;  // the best distinct rival when kAmbiguous
  // Pose uncertainty, map frame, (x, y, z, roll, pitch, yaw) in m and rad about the map axes
  // (ROS order): meaningful when kLocalized (zero otherwise).
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  // Under the answer's pose (the best pose tried when not localized): the share of the nearby
  // query trees (those within ratio_range, at least min_ratio_trees) inside the map's coverage,
  // and the nearby trees inside it (the only evidence for or against the pose). Zero when no pose
  // was tried (kTooFewTrees, kNoMatchingConstellation).
  double coverage_share = 0;
  int trees_in_coverage = 0;
  int hypotheses = 0;         // pose hypotheses that passed the quick check
  int triangles = 0;          // query triangles looked up
  int64_t poses_checked = 0;  // triangle matches whose pose was checked
};

// Throws std::invalid_argument for invalid options; every outcome of a valid query is a value.
RelocalizeResult Relocalize(const MapIndex& index, const RelocalizeQuery& query,
                            const RelocalizerOptions& options = {});

// Local refinement from a close guess (tracking: the previous pose moved by odometry). Only ICP
// around the guess, no search, so it cannot tell two places apart: the caller must know the guess
// is within about a metre. Headings tried: `yaw_window` (rad) around the guess's, and the few
// that best align the query's bearings with the map's seen from the guess (a missed turn). Same
// acceptance tests as Relocalize except the ambiguity margin (confidence is 1 when accepted).
RelocalizeResult RefineNear(const MapIndex& index, const RelocalizeQuery& query,
                            const Pose3& map_from_sensor_guess, double yaw_window = 0.0,
                            const RelocalizerOptions& options = {});

// m^2, the area Relocalize(index, query, options) searches for the look-elsewhere test: the
// positions from which the query's nearby trees see into the map's coverage, or the prior's disc
// when smaller (other_search_area not included). What a question over many maps sums over the
// other maps into each one's other_search_area.
double QuerySearchArea(const MapIndex& index, const RelocalizeQuery& query,
                       const RelocalizerOptions& options = {});

const char* ToString(RelocalizeStatus status);
const char* ToString(RelocalizeReason reason);

}  // namespace forestmap::algorithms
