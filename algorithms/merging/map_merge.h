#pragma once
// Merging per-frame tree detections into a shared tree map (issue 5).
//
// Method (after the tree database of Park & Park 2023, sec. 2.5: a detected
// tree is associated with the nearest database tree inside a recognition threshold and the
// database keeps a count-weighted average; unmatched trees start new entries): every detection
// is moved to the map frame with the frame's full 6-DoF pose, weighted by range, fit score and
// DBH reliability, and associated one-to-one per frame (greedy by Mahalanobis distance, gated in
// position and DBH) with the nearby map trees. A tree's state is a PURE FUNCTION of its
// observations, kept as order-independent sufficient statistics (weighted moments, Chan et al.
// 1979 pairwise update), so removing one source is "recompute from the rest"
// (EstimateFromObservations). New trees start as candidates and are confirmed once seen from
// `promotion_views` distinct sensor positions; surveyed trees are confirmed prior observations.
// RebuildTrees re-merges each connected component of the observations in canonical order and
// consolidates it (ConsolidateTrees: re-association and duplicate merging), so the map is a
// pure function of the set of observations, whatever the order or batching of the uploads.
//
// Frames and units as in algorithms/core/geometry.h. Thread-safety: free functions, no state.

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

enum class TreeStatus { kCandidate, kConfirmed };

const char* ToString(TreeStatus status);

// Weighted mean and scatter of a scalar or a 2-D point: sum of weights, weighted mean and
// m2 = sum w |x - mean|^2. Add and Merge are exact in any order up to rounding.
struct WeightedMoments1 {
  double weight = 0;  // sum of weights
  double mean = 0;
  double m2 = 0;
  int count = 0;  // observations with a positive weight
  void Add(double value, double w);
  void Merge(const WeightedMoments1& other);
};
struct WeightedMoments2 {
  double weight = 0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  double m2 = 0;  // sum w |p - mean|^2 (both axes)
  int count = 0;
  void Add(const Eigen::Vector2d& value, double w);
  void Merge(const WeightedMoments2& other);
};

// One tree of a shared map, in the map frame. All derived fields (position, dbh, sigmas,
// observations, distinct_views, status) follow from the statistics (xy, z, dbh_stats,
// view_anchors, surveyed) through Finalize; a store keeps either every field or the observation
// rows and calls EstimateFromObservations.
struct TreeEstimate {
  int64_t id = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m; z NaN when no observation had one
  double dbh = kUnknown;                               // m, NaN unknown
  double position_sigma = kUnknown;  // m, 1-sigma horizontal uncertainty of the mean
  double dbh_sigma = kUnknown;       // m, 1-sigma uncertainty of the DBH mean
  int observations = 0;              // rows, including a survey prior
  int distinct_views = 0;            // sensor positions >= min_view_separation apart (capped)
  TreeStatus status = TreeStatus::kCandidate;
  bool surveyed = false;    // has a survey prior observation (always confirmed)
  bool summarized = false;  // has a summary row (ObservationSummary) of folded rows

  // Sufficient statistics.
  WeightedMoments2 xy;         // horizontal position, weights weight_xy
  WeightedMoments1 z;          // height, weights weight_xy, observations with a known z
  WeightedMoments1 dbh_stats;  // DBH, weights weight_dbh, observations with a known DBH
  std::vector<Eigen::Vector2d> view_anchors;  // m, map xy; at most kMaxViewAnchors
  static constexpr int kMaxViewAnchors = 8;
};

// The statistics of the rows of one tree folded into one summary row (SummaryObservation): what
// EstimateFromObservations takes from them, so that the summary stands for them exactly (up to
// rounding). A summary row defines its tree, as a survey prior does: it is never re-associated.
struct ObservationSummary {
  WeightedMoments2 xy;
  WeightedMoments1 z;
  WeightedMoments1 dbh;
  int rows = 0;                               // rows folded (incl. a survey prior)
  bool surveyed = false;                      // one of them is a survey prior
  std::vector<Eigen::Vector2d> view_anchors;  // at most TreeEstimate::kMaxViewAnchors
};

// One tree seen in one frame (or one survey prior, or a summary of rows), in the MAP frame: a row
// to persist.
struct TreeObservation {
  int64_t tree_id = 0;      // the tree it belongs to; negative = placeholder of a new tree
  std::string source;       // drone / upload / "survey"
  int64_t frame_id = 0;     // frame within the source
  int detection_index = 0;  // index in FrameObservations::trees (-1 for a survey prior)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m, map frame; z NaN unknown
  double dbh = kUnknown;                               // m
  double weight_xy = 0;   // 1/m^2, inverse variance of the horizontal position (per axis)
  double weight_dbh = 0;  // 1/m^2, inverse variance of the DBH; 0 = DBH not used
  Eigen::Vector3d sensor_position = Eigen::Vector3d::Zero();  // m, map frame
  bool prior = false;  // a surveyed tree: confirms the tree on its own
  // Set on a summary row (source kSummarySource): the rows it stands for. position, dbh and the
  // weights are then its means and total weights.
  std::shared_ptr<const ObservationSummary> summary;
  // Whether the row defines its tree (a survey prior or a summary): such rows start their trees
  // and are never re-associated.
  bool defines_tree() const { return prior || summary != nullptr; }
};

// The source of summary rows (a name no drone is given: sources are not empty).
inline constexpr const char* kSummarySource = "";

struct FrameObservations {
  std::string source;
  int64_t frame_id = 0;
  Pose3 map_from_sensor = Pose3::Identity();  // full 6-DoF: levels tilted frames
  std::vector<DetectedTree> trees;            // sensor frame
};

struct MergeOptions {
  // Observation model: sigma_xy = hypot(base, per_m * range) / (score_floor + (1 - score_floor)
  // * score); a missing score counts as 0.5.
  double sigma_xy_base = 0.05;    // m
  double sigma_xy_per_m = 0.004;  // m of sigma per m of horizontal range
  double score_floor = 0.5;       // [0, 1], weight share kept by a zero-score fit
  double sigma_dbh_base = 0.03;   // m
  double sigma_dbh_per_m = 0.0;   // m of DBH sigma per m of range
  double max_range = 20.0;        // m, horizontal; farther detections are not merged
  double min_dbh = 0.02;          // m, smaller (or non-positive) DBH counts as unknown
  // Association.
  double gate_distance = 0.6;         // m, hard horizontal gate
  double gate_sigmas = 4.0;           // Mahalanobis gate (combined tree + observation sigma)
  double pose_sigma = 0.10;           // m, added in quadrature: pose / map registration error
  double dbh_gate_abs = 0.15;         // m, DBH difference always accepted
  double dbh_gate_rel = 0.5;          // of the larger DBH, DBH difference also accepted
  double dbh_cost = 1.0;              // association cost per (DBH difference / gate)^2
  double dbh_outlier_distance = 0.2;  // m, a DBH outside the gate still joins a tree this near
  // Promotion.
  int promotion_views = 3;           // distinct views that confirm a candidate
  double min_view_separation = 1.0;  // m, sensor positions closer than this are one view
  // Survey prior.
  double survey_sigma_xy = 0.05;   // m
  double survey_sigma_dbh = 0.01;  // m
  // Consolidation.
  double duplicate_distance = 0.3;  // m, closer trees may be one stem (MergeDuplicates)
  double max_shared_frames = 0.4;   // share of the fewer frames of two trees that see both
  int min_shared_frames = 3;        // frames; fewer seeing both do not make two trees
  int consolidate_iterations = 6;   // re-association sweeps
  // Folding (a server's merge, server/app/map_merger.h): once a tree holds this many individual
  // stored rows, they are folded into one summary row (SummaryObservation), so that a rebuild
  // reads and re-associates at most about this many rows per tree whatever its history.
  int fold_rows = 32;
  void Check() const;  // throws std::invalid_argument naming the field
};

struct MergeResult {
  // Per detected tree (index into FrameObservations::trees): the id of the tree it updated or
  // created (negative placeholder -(k+1) for new_trees[k]), or 0 when it was not merged
  // (out of range, invalid).
  std::vector<int64_t> assignment;
  std::vector<TreeEstimate> updated_trees;    // existing trees that received an observation
  std::vector<TreeEstimate> new_trees;        // new candidates, ids -1, -2, ...
  std::vector<TreeObservation> observations;  // rows to persist (tree_id as in assignment)
  std::vector<int64_t> promoted_ids;          // trees confirmed by this frame (may be < 0)
  int associated = 0, created = 0, skipped = 0;
};

// Merges one frame into the trees near it (pass at least the trees within max_range +
// gate_distance of the sensor; passing more is harmless). Deterministic. Throws
// std::invalid_argument for invalid options or a non-finite pose.
MergeResult MergeFrame(std::span<const TreeEstimate> nearby_map_trees,
                       const FrameObservations& frame, const MergeOptions& options = {});

// Replaces placeholder ids (-(k+1) -> new_ids[k]) everywhere in `result`.
void ResolveNewIds(MergeResult& result, std::span<const int64_t> new_ids);

// The observation rows of one frame (weights and map-frame positions), without association:
// tree_id = 0. Detections beyond max_range or with a non-finite position are left out.
std::vector<TreeObservation> ObserveFrame(const FrameObservations& frame,
                                          const MergeOptions& options = {});

// A surveyed tree as a prior observation (source "survey", prior = true).
TreeObservation SurveyObservation(const MapTree& tree, const MergeOptions& options = {});

// One summary row of tree `tree_id` standing for `rows` (rows of that tree, summary rows among
// them too), added in canonical order: EstimateFromObservations gives the same tree from it as
// from the rows, up to rounding. Source kSummarySource, frame 0, detection index -2; position,
// DBH and weights are the rows' weighted means and total weights; the sensor position is the
// first view anchor (the position when there is none). Throws std::invalid_argument without rows.
TreeObservation SummaryObservation(int64_t tree_id, std::span<const TreeObservation> rows,
                                   const MergeOptions& options = {});

// Adds one observation to a tree's statistics and re-derives its fields.
void AddObservation(TreeEstimate& tree, const TreeObservation& observation,
                    const MergeOptions& options = {});

// The tree as a pure function of its observations (used after removing a source's rows, and
// for surveyed trees). Observations whose tree_id differs from `id` are still used. Equal to the
// incremental result for the same observations in the same order.
TreeEstimate EstimateFromObservations(int64_t id, std::span<const TreeObservation> observations,
                                      const MergeOptions& options = {});

struct ConsolidateResult {
  std::vector<TreeEstimate> trees;            // every surviving tree, ids kept from the input
                                              // (RebuildTrees: or new, >= next_free_id)
  std::vector<int64_t> removed_ids;           // input trees merged away or left empty
  std::vector<TreeObservation> observations;  // all input rows with their (new) tree_id
  int reassigned = 0;                         // rows whose tree changed
  int merged = 0;                             // duplicate pairs merged
};

// Re-associates the observations of a region with its trees (k-means style, one-to-one per
// frame, canonical row order) and merges duplicate trees (closer than duplicate_distance, and
// overlapping or rarely seen in one frame together; the smaller id survives). The result depends
// on the SET of rows and trees, not on their order. `trees` must hold every tree that the
// observations refer to.
ConsolidateResult ConsolidateTrees(std::span<const TreeEstimate> trees,
                                   std::span<const TreeObservation> observations,
                                   const MergeOptions& options = {});

// The map as a pure function of the SET of observation rows: each connected component of the
// rows (algorithms/merging/observation_components.h) is merged afresh on its own, frame by frame in
// canonical order (frame, source, detection) as into an empty map (survey priors keep their
// trees), then consolidated (ConsolidateTrees). The current association of the rows is
// forgotten; so is the order in which they arrived (concurrent uploads) and how they were
// batched: the same rows give the same trees to the last bit, only the ids may differ. Rows
// elsewhere never change a component's trees, which is what lets a server rebuild only the
// components that new rows touch and still hold exactly the map one rebuild of all rows gives.
// A new tree takes the previous id most of its rows had, when still free (components in the
// order of their first canonical row), else a new id counting up from `next_free_id`.
// `trees` must hold every tree that the observations refer to; given trees that keep no row are
// in removed_ids. A summary row (SummaryObservation) is a fixed part of its tree, as a survey
// prior is: its tree keeps its id and is merged with no other summarized or surveyed tree (a tree
// merged into it takes its id), and only the other rows are merged afresh around it. A map whose
// trees fold their rows is therefore a function of the set of its rows only up to when each tree
// folded: the association of folded rows is fixed (docs/design.md).
ConsolidateResult RebuildTrees(std::span<const TreeEstimate> trees,
                               std::span<const TreeObservation> observations, int64_t next_free_id,
                               const MergeOptions& options = {});

}  // namespace forestmap::algorithms
