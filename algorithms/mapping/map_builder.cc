#include "algorithms/mapping/map_builder.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "algorithms/mapping/map_builder_internal.h"
#include "algorithms/mapping/tree_adjustment.h"

namespace forestmap::algorithms {

const char* ToString(FrameFix fix) {
  switch (fix) {
    case FrameFix::kFirst:
      return "first";
    case FrameFix::kTracked:
      return "tracked";
    case FrameFix::kRelocalized:
      return "relocalized";
    case FrameFix::kGlobal:
      return "global";
    case FrameFix::kDeadReckoned:
      return "dead_reckoned";
  }
  return "?";
}

void MapBuilderOptions::Check() const {
  merge.Check();
  relocalizer.Check();
  leveling.Check();
  pose_graph.Check();
  auto require = [](bool ok, const char* field) {
    if (!ok) throw std::invalid_argument(std::string("MapBuilderOptions.") + field + " is invalid");
  };
  require(icp_range > 0, "icp_range (must be > 0 m)");
  require(icp_gates.size() >= 2 && *std::min_element(icp_gates.begin(), icp_gates.end()) > 0,
          "icp_gates (needs >= 2 gates, each > 0 m)");
  require(icp_iterations >= 1, "icp_iterations (must be >= 1)");
  require(min_inliers >= 3, "min_inliers (must be >= 3)");
  require(min_inlier_fraction >= 0 && min_inlier_fraction <= 1, "min_inlier_fraction ([0, 1])");
  require(max_correction > 0, "max_correction (must be > 0 m)");
  require(max_height_step >= 0, "max_height_step (must be >= 0 m)");
  require(prior_radius > 0, "prior_radius (must be > 0 m)");
  require(global_after >= 1, "global_after (must be >= 1)");
  require(odometry_sigma_xy > 0 && odometry_sigma_yaw > 0, "odometry_sigma_* (must be > 0)");
  require(velocity_sigma_xy > 0 && velocity_sigma_yaw > 0, "velocity_sigma_* (must be > 0)");
  require(measurement_sigma_xy > 0 && measurement_sigma_yaw > 0,
          "measurement_sigma_* (must be > 0)");
  require(loop_min_age >= 1, "loop_min_age (must be >= 1 frame)");
  require(loop_min_old_trees >= 3, "loop_min_old_trees (must be >= 3)");
  require(loop_min_inliers >= 3, "loop_min_inliers (must be >= 3)");
  require(loop_yaw_search >= 0, "loop_yaw_search (must be >= 0 rad)");
  require(yaw_search >= 0, "yaw_search (must be >= 0 rad)");
  require(loop_min_correction >= 0, "loop_min_correction (must be >= 0 m)");
  require(loop_min_gain >= 1, "loop_min_gain (must be >= 1)");
  require(loop_confirm_frames >= 1, "loop_confirm_frames (must be >= 1)");
  require(loop_confirm_distance > 0, "loop_confirm_distance (must be > 0 m)");
  require(loop_search_radius > 0, "loop_search_radius (must be > 0 m)");
  require(loop_search_every >= 1, "loop_search_every (must be >= 1)");
  require(loop_cooldown >= 0, "loop_cooldown (must be >= 0)");
  require(final_adjustment_rounds >= 0, "final_adjustment_rounds (must be >= 0)");
  require(adjustment_max_range > 0, "adjustment_max_range (must be > 0 m)");
  require(final_max_range > 0, "final_max_range (must be > 0 m)");
  require(height_sigma > 0 && height_step_sigma > 0 && height_outlier_scale > 0,
          "height_sigma, height_step_sigma, height_outlier_scale (must be > 0 m)");
  adjustment.Check();
  search_index.Check();
}

MapBuilder::Impl::LocalMap MapBuilder::Impl::MakeLocalMap(const std::vector<TreeEstimate>& trees) {
  LocalMap local;
  std::vector<KdTree<double, 2>::Point> xy;
  for (const TreeEstimate& tree : trees) {
    local.points.push_back(tree.position);
    const double sigma = IsKnown(tree.position_sigma) ? tree.position_sigma : 0.0;
    local.variances.push_back(sigma * sigma);
    local.ids.push_back(tree.id);
    xy.push_back({tree.position.x(), tree.position.y()});
  }
  local.xy = std::make_unique<KdTree<double, 2>>(std::move(xy));
  return local;
}

BuilderStep MapBuilder::Impl::AddFrame(const BuilderFrame& input) {
  StoredFrame frame = Prepare(input);
  const int index = static_cast<int>(frames_.size());
  BuilderStep step;
  if (index == 0) {
    frame.pose = Pose4{};
    ekf_.Reset(frame.pose, options_.measurement_sigma_xy, options_.measurement_sigma_yaw);
    step.fix = FrameFix::kFirst;
    Commit(std::move(frame), step);
    return step;
  }
  const Pose4 predicted = Predict(input, frames_.back());
  Fix fix = Localize(frame, predicted);
  if (!fix.ok) {
    ++failures_;
    frame.pose = predicted;
    step.fix = FrameFix::kDeadReckoned;
    frames_.push_back(std::move(frame));
    AddSequentialEdge(/*tracked=*/false);
    step.map_from_sensor = MapFromSensor(frames_.back());
    return step;
  }
  failures_ = 0;
  ekf_.Update(fix.pose, std::max(options_.measurement_sigma_xy, fix.sigma_xy),
              std::max(options_.measurement_sigma_yaw, fix.sigma_yaw));
  // Detected stem heights are biased per frame by metres (real data: the median stem height
  // under the sensor jumps from -2 to -15 m within 4 frames of 2 m), so the tree-map height
  // fix may move the sensor at most max_height_step per frame.
  const double z_predicted = frames_.back().pose.translation.z();
  frame.pose =
      ekf_.Pose(z_predicted + std::clamp(fix.pose.translation.z() - z_predicted,
                                         -options_.max_height_step, options_.max_height_step));
  step.fix = fix.how;
  step.inliers = fix.inliers;
  step.rmse = fix.rmse;
  if (options_.loop_closure && index - last_closure_ >= options_.loop_cooldown) {
    TryCloseLoop(frame, index, step);
  }
  Commit(std::move(frame), step);
  return step;
}

// Joint adjustments of poses and trees (each followed by a re-merge), then the final merge and
// consolidation. The final map merges only detections within final_max_range: tracking needs the
// long views, the map does not (far detections are biased and split stems; Wild_V01: pairs of
// trees closer than 0.5 m 991 -> 589 with 20 m, as many as merging the frames with their true
// poses gives).
void MapBuilder::Impl::Finish() {
  for (int round = 0; round < options_.final_adjustment_rounds; ++round) Adjust();
  if (options_.final_max_range < options_.merge.max_range) {
    MergeOptions final_merge = options_.merge;
    final_merge.max_range = options_.final_max_range;
    Remerge(final_merge);
  }
  if (options_.final_consolidate) map_->Consolidate();
}

void MapBuilder::Impl::Adjust() {
  std::unordered_map<int64_t, int> tree_index;
  std::vector<Eigen::Vector3d> trees;
  std::vector<TreeAdjustmentObservation> observations;
  const double weight_z = 1.0 / (options_.height_sigma * options_.height_sigma);
  // Far detections are biased towards the sensor (Wild_V01: 1 mm per m beyond 20 m) and noisier:
  // ATE 0.13 m with adjustment_max_range 20 m, 0.23 m with 40 m.
  for (const TreeObservation& row : map_->observations()) {
    const int frame = static_cast<int>(row.frame_id);
    const Eigen::Vector3d& level = frames_[frame].level_trees[row.detection_index].position;
    if (level.head<2>().norm() > options_.adjustment_max_range) continue;
    const auto [it, inserted] = tree_index.try_emplace(row.tree_id, trees.size());
    if (inserted) trees.push_back(row.position);
    TreeAdjustmentObservation o;
    o.frame = frame;
    o.tree = it->second;
    o.level_position = level;
    o.weight_xy = row.weight_xy;
    o.weight_z = std::isfinite(row.position.z()) ? weight_z : 0.0;
    observations.push_back(o);
  }
  std::vector<Pose4> poses;
  for (const StoredFrame& frame : frames_) poses.push_back(frame.pose);
  const TreeAdjustmentResult adjusted =
      AdjustTrees(std::move(poses), std::move(trees), observations, {}, options_.adjustment);
  std::vector<double> apparent;
  for (size_t i = 0; i < frames_.size(); ++i) {
    frames_[i].pose = adjusted.poses[i];
    apparent.push_back(adjusted.poses[i].translation.z());
  }
  const std::vector<double> heights =
      SmoothHeights(apparent, options_.height_step_sigma, options_.height_outlier_scale);
  // The first frame defines the map frame: its sensor stays at height 0.
  for (size_t i = 0; i < frames_.size(); ++i) {
    frames_[i].height_offset = apparent[i] - (heights[i] - heights[0] + apparent[0]);
  }
  Remerge();
}

std::vector<Pose3> MapBuilder::Impl::Poses() const {
  std::vector<Pose3> out;
  for (const StoredFrame& frame : frames_) out.push_back(MapFromSensor(frame));
  return out;
}

Pose3 MapBuilder::Impl::MapFromSensor(const StoredFrame& frame) {
  Pose3 level = Pose3::Identity();
  level.linear() = frame.level_from_sensor;
  Pose4 sensor = frame.pose;
  sensor.translation.z() -= frame.height_offset;
  return ToPose3(sensor) * level;
}

MapBuilder::Impl::StoredFrame MapBuilder::Impl::Prepare(const BuilderFrame& input) const {
  StoredFrame frame;
  frame.frame_id = input.frame_id;
  const LevelingResult level = LevelSensor(input.trees, input.gravity, options_.leveling);
  frame.level_from_sensor = level.level_from_sensor;
  for (const DetectedTree& tree : input.trees) {
    if (!tree.position.head<2>().allFinite()) continue;
    DetectedTree moved = tree;
    Eigen::Vector3d p = tree.position;
    if (!std::isfinite(p.z())) p.z() = 0;
    moved.position = level.level_from_sensor * p;
    if (tree.HasAxis()) moved.axis = level.level_from_sensor * tree.axis;
    const double range = moved.position.head<2>().norm();
    if (range <= options_.icp_range) {
      frame.query.push_back(moved.position);
      const double sigma =
          std::hypot(options_.merge.sigma_xy_base, options_.merge.sigma_xy_per_m * range);
      frame.query_weights.push_back(1.0 / (sigma * sigma));
      frame.query_index.push_back(static_cast<int>(frame.level_trees.size()));
    }
    frame.level_trees.push_back(moved);
  }
  return frame;
}

void MapBuilder::Impl::NoteObservations(const std::vector<TreeObservation>& rows) {
  for (const TreeObservation& row : rows) {
    const int frame = static_cast<int>(row.frame_id);
    const auto [it, inserted] = first_frame_.try_emplace(row.tree_id, frame);
    if (!inserted) it->second = std::min(it->second, frame);
  }
}

void MapBuilder::Impl::AddSequentialEdge(bool tracked) {
  const int to = static_cast<int>(frames_.size()) - 1;
  if (to < 1) return;
  PoseGraphEdge edge;
  edge.from = to - 1;
  edge.to = to;
  edge.measurement = Between(frames_[to - 1].pose, frames_[to].pose);
  if (tracked) {
    edge.sigma = Eigen::Vector4d(options_.measurement_sigma_xy, options_.measurement_sigma_xy,
                                 options_.measurement_sigma_xy, options_.measurement_sigma_yaw);
  } else {
    edge.sigma = Eigen::Vector4d(options_.velocity_sigma_xy, options_.velocity_sigma_xy,
                                 options_.velocity_sigma_xy, options_.velocity_sigma_yaw);
  }
  edges_.push_back(edge);
}

void MapBuilder::Impl::Commit(StoredFrame frame, BuilderStep& step) {
  const int index = static_cast<int>(frames_.size());
  if (!frames_.empty()) velocity_ = Between(frames_.back().pose, frame.pose);
  frame.merged = true;
  frames_.push_back(std::move(frame));
  if (!step.loop_closed) {
    AddSequentialEdge(/*tracked=*/true);
    FrameObservations observations;
    observations.source = "builder";
    observations.frame_id = index;
    observations.trees = frames_.back().level_trees;
    // level_trees are levelled: their pose is the 4-DoF one.
    observations.map_from_sensor = ToPose3(frames_.back().pose);
    NoteObservations(map_->Merge(observations).observations);
  }
  step.map_from_sensor = MapFromSensor(frames_.back());
}

void MapBuilder::Impl::Remerge(const MergeOptions& merge) {
  map_ = std::make_unique<MergedMap>(merge);
  first_frame_.clear();
  for (size_t i = 0; i < frames_.size(); ++i) {
    if (!frames_[i].merged) continue;
    FrameObservations observations;
    observations.source = "builder";
    observations.frame_id = static_cast<int64_t>(i);
    observations.map_from_sensor = ToPose3(frames_[i].pose);
    observations.trees = frames_[i].level_trees;
    NoteObservations(map_->Merge(observations).observations);
  }
}

MapBuilder::MapBuilder(const MapBuilderOptions& options) : impl_(std::make_unique<Impl>(options)) {}
MapBuilder::~MapBuilder() = default;
BuilderStep MapBuilder::AddFrame(const BuilderFrame& frame) { return impl_->AddFrame(frame); }
void MapBuilder::Finish() { impl_->Finish(); }
std::vector<Pose3> MapBuilder::Poses() const { return impl_->Poses(); }
const MergedMap& MapBuilder::map() const { return impl_->map(); }
std::vector<MapTree> MapBuilder::ConfirmedTrees() const { return map().ConfirmedMapTrees(); }
int MapBuilder::loop_closures() const { return impl_->loop_closures(); }
int MapBuilder::frames() const { return impl_->frames(); }

}  // namespace forestmap::algorithms
