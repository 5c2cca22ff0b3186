#pragma once
// Mapping an unknown forest from tree detections alone (no poses): tree-based SLAM.
//
// The first frame, levelled by its stem axes, defines the map frame. Every later frame is
// levelled, predicted by a small EKF on (x, y, yaw) (as in Park & Park
// 2023: odometry when given, else a constant-velocity model with a generous
// noise), localized by tree-to-tree ICP against the map so far around the prediction (falling
// back to Relocalize with a prior radius, then to a global search), fused in the EKF and merged
// into the map (map_merge.h). Loop closure: each frame is also matched against trees first
// mapped long ago only; when that match moves the frame by more than a threshold, a relative-pose
// edge to the old frame that saw those trees joins the pose graph (consecutive frames linked by
// their tracked relative poses), the 4-DoF graph is optimised (pose_graph.h) and the map is
// re-merged from all frames with the corrected poses, so a revisited tree does not appear twice.
//
// Frames and units as in algorithms/core/geometry.h. Not thread-safe: one builder per mapping run.

#include <memory>
#include <optional>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/leveling.h"
#include "algorithms/mapping/pose_graph.h"
#include "algorithms/mapping/tree_adjustment.h"
#include "algorithms/merging/map_merge.h"
#include "algorithms/merging/merged_map.h"
#include "algorithms/relocalization/relocalizer.h"

namespace forestmap::algorithms {

struct MapBuilderOptions {
  MapBuilderOptions() {
    merge.max_range = 40.0;  // long views keep the tracking overlap
    // Fallback searches index a few hundred trees around the prediction, each time: a smaller
    // triangle budget than a served map's (Oxford_Stein: half the build time, ATE 0.21 -> 0.15 m).
    search_index.min_index_triangles = 50000;
  }
  MergeOptions merge;
  RelocalizerOptions relocalizer;  // fallback searches
  MapIndexOptions search_index;    // ... and the index they build over the local map
  LevelingOptions leveling;
  // Tree ICP (frame to map), from the prediction.
  double icp_range = 40.0;  // m, query trees used (horizontal range)
  std::vector<double> icp_gates = {2.0, 1.2, 0.8, 0.5, 0.35};  // m, association gate per round
  int icp_iterations = 4;                                      // per gate
  double yaw_search = 0.45;          // rad, first-gate headings tried around the prediction
  int min_inliers = 8;               // fewer -> fall back to a search
  double min_inlier_fraction = 0.4;  // inliers / query trees within icp_range
  double max_correction = 3.0;       // m, ICP may move the prediction at most this far
  double max_height_step = 0.15;     // m, height change per frame a fix may make
  double prior_radius = 15.0;        // m, Relocalize radius after an ICP failure
  int global_after = 3;              // failed frames before a whole-map search
  // EKF noise (1-sigma): odometry per frame, or constant velocity without odometry.
  double odometry_sigma_xy = 0.1;        // m
  double odometry_sigma_yaw = 0.02;      // rad
  double velocity_sigma_xy = 1.5;        // m
  double velocity_sigma_yaw = 0.3;       // rad
  double measurement_sigma_xy = 0.05;    // m, floor of an ICP fix's sigma
  double measurement_sigma_yaw = 0.003;  // rad
  // Loop closure.
  bool loop_closure = true;
  int loop_min_age = 60;               // frames: trees first mapped this long ago are "old"
  int loop_min_old_trees = 15;         // old trees within icp_range needed to try
  int loop_min_inliers = 25;           // and min_inlier_fraction of the query trees
  double loop_yaw_search = 0.1;        // rad, headings tried matching old trees
  double loop_min_correction = 0.15;   // m, smaller corrections are not worth an edge
  double loop_min_gain = 1.5;          // old-tree inliers: corrected / tracked pose, at least
  int loop_confirm_frames = 6;         // a second detection within this many frames ...
  double loop_confirm_distance = 0.5;  // m, ... with a correction this close confirms it
  double loop_search_radius = 8.0;     // m, prior radius when ICP does not find the old trees
  int loop_search_every = 5;           // frames between prior-radius searches for a loop
  int loop_cooldown = 3;               // frames after a closure without a new one
  PoseGraphOptions pose_graph;
  int final_adjustment_rounds = 2;  // Finish(): joint adjustments (tree_adjustment.h)
  TreeAdjustmentOptions adjustment;
  double adjustment_max_range = 20.0;  // m, farther detections do not enter the adjustment
  double height_sigma = 0.3;           // m, 1-sigma of a detected stem's height
  // Sensor heights from the adjusted apparent ones (SmoothHeights, tree_adjustment.h).
  double height_step_sigma = 0.2;     // m, 1-sigma height change between consecutive frames
  double height_outlier_scale = 0.3;  // m, Cauchy scale of a frame's apparent height
  double final_max_range = 20.0;      // m, the final map merges only nearer detections
  bool final_consolidate = true;
  void Check() const;  // throws std::invalid_argument naming the field
};

struct BuilderFrame {
  int64_t frame_id = 0;
  std::vector<DetectedTree> trees;         // sensor frame
  std::optional<Eigen::Vector3d> gravity;  // gravity (down) in the sensor frame, when known
  std::optional<Pose3> odometry;           // previous_sensor_from_sensor, when known
};

enum class FrameFix {
  kFirst,         // the first frame: defines the map frame
  kTracked,       // ICP around the prediction
  kRelocalized,   // Relocalize with a prior radius
  kGlobal,        // Relocalize over the whole map
  kDeadReckoned,  // no fix: the prediction is kept and the frame is not merged
};

const char* ToString(FrameFix fix);

struct BuilderStep {
  FrameFix fix = FrameFix::kDeadReckoned;
  Pose3 map_from_sensor = Pose3::Identity();
  int inliers = 0;
  double rmse = 0;             // m, horizontal, of the fix's matches
  bool loop_closed = false;    // this frame closed a loop (graph optimised, map re-merged)
  double loop_correction = 0;  // m, how far the old trees moved this frame
};

class MapBuilder {
 public:
  explicit MapBuilder(const MapBuilderOptions& options = {});
  ~MapBuilder();
  MapBuilder(const MapBuilder&) = delete;
  MapBuilder& operator=(const MapBuilder&) = delete;

  BuilderStep AddFrame(const BuilderFrame& frame);

  // Final consolidation (re-association, duplicate merging). Call once after the last frame.
  void Finish();

  // map_from_sensor of every added frame, in order (after loop-closure corrections).
  std::vector<Pose3> Poses() const;
  const MergedMap& map() const;
  std::vector<MapTree> ConfirmedTrees() const;
  int loop_closures() const;
  int frames() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace forestmap::algorithms
