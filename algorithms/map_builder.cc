#include "algorithms/map_builder.h"

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "algorithms/map_index.h"
#include "algorithms/planar_ekf.h"
#include "algorithms/tree_adjustment.h"
#include "algorithms/tree_icp.h"

namespace forestmap::algorithms {

const char* ToString(FrameFix fix) {
  switch (fix) {
    case FrameFix::kFirst: return "first";
    case FrameFix::kTracked: return "tracked";
    case FrameFix::kRelocalized: return "relocalized";
    case FrameFix::kGlobal: return "global";
    case FrameFix::kDeadReckoned: return "dead_reckoned";
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

namespace {

struct StoredFrame {
  int64_t frame_id = 0;
  Eigen::Matrix3d level_from_sensor = Eigen::Matrix3d::Identity();
  std::vector<DetectedTree> level_trees;    // levelled sensor frame
  std::vector<Eigen::Vector3d> query;       // levelled positions within icp_range
  std::vector<double> query_weights;
  std::vector<int> query_index;             // into level_trees
  Pose4 pose;                  // map_from_level; z is the apparent height (where the stems put it)
  double height_offset = 0;    // m, apparent minus sensor height (this frame's stems' height bias)
  bool merged = false;
};

// Map trees near a place, with a k-d tree, for ICP.
struct LocalMap {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> variances;  // m^2, of each tree's mean position
  std::vector<int64_t> ids;
  std::unique_ptr<KdTree<double, 2>> xy;
};

LocalMap MakeLocalMap(const std::vector<TreeEstimate>& trees) {
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

}  // namespace

class MapBuilder::Impl {
 public:
  explicit Impl(const MapBuilderOptions& options)
      : options_(options), map_(std::make_unique<MergedMap>(options.merge)) {
    options_.Check();
  }

  BuilderStep AddFrame(const BuilderFrame& input) {
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
    frame.pose = ekf_.Pose(z_predicted + std::clamp(fix.pose.translation.z() - z_predicted,
                                                    -options_.max_height_step,
                                                    options_.max_height_step));
    step.fix = fix.how;
    step.inliers = fix.inliers;
    step.rmse = fix.rmse;
    if (options_.loop_closure && index - last_closure_ >= options_.loop_cooldown) {
      TryCloseLoop(frame, index, step);
    }
    Commit(std::move(frame), step);
    return step;
  }

  void Finish() {
    for (int round = 0; round < options_.final_adjustment_rounds; ++round) Adjust();
    if (options_.final_max_range < options_.merge.max_range) {
      MergeOptions final_merge = options_.merge;
      final_merge.max_range = options_.final_max_range;
      Remerge(final_merge);
    }
    if (options_.final_consolidate) map_->Consolidate();
  }

  // Joint planar adjustment of all poses and trees (tree_adjustment.h), then a re-merge with the
  // adjusted poses (associations follow the better poses).
  void Adjust() {
    std::unordered_map<int64_t, int> tree_index;
    std::vector<Eigen::Vector3d> trees;
    std::vector<TreeAdjustmentObservation> observations;
    const double weight_z = 1.0 / (options_.height_sigma * options_.height_sigma);
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

  std::vector<Pose3> Poses() const {
    std::vector<Pose3> out;
    for (const StoredFrame& frame : frames_) out.push_back(MapFromSensor(frame));
    return out;
  }
  const MergedMap& map() const { return *map_; }
  int loop_closures() const { return loop_closures_; }
  int frames() const { return static_cast<int>(frames_.size()); }

 private:
  struct Fix {
    bool ok = false;
    FrameFix how = FrameFix::kTracked;
    Pose4 pose;
    int inliers = 0;
    double rmse = 0;
    double sigma_xy = 0, sigma_yaw = 0;
    std::vector<std::pair<int, int>> matches;  // (query index, local map index)
  };

  static Pose3 MapFromSensor(const StoredFrame& frame) {
    Pose3 level = Pose3::Identity();
    level.linear() = frame.level_from_sensor;
    Pose4 sensor = frame.pose;
    sensor.translation.z() -= frame.height_offset;
    return ToPose3(sensor) * level;
  }

  StoredFrame Prepare(const BuilderFrame& input) const {
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
        const double sigma = std::hypot(options_.merge.sigma_xy_base,
                                        options_.merge.sigma_xy_per_m * range);
        frame.query_weights.push_back(1.0 / (sigma * sigma));
        frame.query_index.push_back(static_cast<int>(frame.level_trees.size()));
      }
      frame.level_trees.push_back(moved);
    }
    return frame;
  }

  Pose4 Predict(const BuilderFrame& input, const StoredFrame& previous) {
    Pose4 relative = velocity_;
    double sigma_xy = options_.velocity_sigma_xy, sigma_yaw = options_.velocity_sigma_yaw;
    if (input.odometry) {
      // previous_level_from_level = L_prev * previous_sensor_from_sensor * L^-1 (this frame's
      // levelling is not known before Prepare, so the odometry's own tilt is used).
      Pose3 prev_level = Pose3::Identity();
      prev_level.linear() = previous.level_from_sensor;
      const Pose3 moved = prev_level * *input.odometry * prev_level.inverse();
      relative = ToPose4(moved);
      sigma_xy = options_.odometry_sigma_xy;
      sigma_yaw = options_.odometry_sigma_yaw;
    }
    // After failed frames the prediction has moved on with the last motion.
    ekf_.Predict(relative, sigma_xy, sigma_yaw);
    return ekf_.Pose(previous.pose.translation.z() + relative.translation.z());
  }

  Fix FromIcp(const TreeIcpResult& icp, const StoredFrame& frame, FrameFix how) const {
    Fix fix;
    fix.how = how;
    fix.pose = icp.map_from_level;
    fix.inliers = icp.inliers;
    fix.rmse = icp.rmse;
    fix.matches = icp.matches;
    const double considered = std::max<size_t>(1, frame.query.size());
    fix.ok = icp.inliers >= options_.min_inliers &&
             icp.inliers >= options_.min_inlier_fraction * considered;
    const double n = std::max(1, icp.inliers);
    fix.sigma_xy = icp.rmse / std::sqrt(n);
    fix.sigma_yaw = icp.rmse / std::sqrt(n) / 10.0;  // ~10 m lever arm of the matched trees
    return fix;
  }

  Fix Localize(const StoredFrame& frame, const Pose4& predicted) {
    const LocalMap local = MakeLocalMap(map_->TreesNear(
        predicted.translation.head<2>(),
        options_.icp_range + options_.max_correction + options_.prior_radius));
    if (local.points.size() >= 3 && failures_ < options_.global_after) {
      const TreeIcpResult icp = TreeIcp(frame.query, frame.query_weights, local.points,
                                        *local.xy, predicted, options_.icp_gates,
                                        options_.icp_iterations, options_.yaw_search,
                                        local.variances);
      Fix fix = FromIcp(icp, frame, FrameFix::kTracked);
      const double moved = (icp.map_from_level.translation - predicted.translation)
                               .head<2>()
                               .norm();
      if (fix.ok && moved <= options_.max_correction) return fix;
    }
    const bool global = failures_ >= options_.global_after;
    std::vector<MapTree> trees;
    if (global) {
      trees = map_->ConfirmedMapTrees();
    } else {
      for (size_t i = 0; i < local.points.size(); ++i) {
        trees.push_back(MapTree{local.ids[i], local.points[i], kUnknown});
      }
    }
    return Search(frame, trees, global ? std::nullopt : std::optional<Pose4>(predicted),
                  options_.prior_radius, global ? FrameFix::kGlobal : FrameFix::kRelocalized);
  }

  // Relocalize (optionally within `radius` of `prior`), then ICP from its answer.
  Fix Search(const StoredFrame& frame, std::vector<MapTree> trees,
             const std::optional<Pose4>& prior, double radius, FrameFix how) const {
    Fix none;
    if (trees.size() < 10) return none;
    const LocalMap local = [&] {
      std::vector<TreeEstimate> as_estimates(trees.size());
      for (size_t i = 0; i < trees.size(); ++i) {
        as_estimates[i].id = trees[i].id;
        as_estimates[i].position = trees[i].position;
      }
      return MakeLocalMap(as_estimates);
    }();
    const MapIndex index(std::move(trees), options_.search_index);
    RelocalizeQuery query;
    query.trees = frame.level_trees;
    query.gravity = Eigen::Vector3d(0, 0, -1);  // already levelled
    if (prior) query.prior = PriorPose{ToPose3(*prior), radius};
    const RelocalizeResult answer = Relocalize(index, query, options_.relocalizer);
    if (answer.status != RelocalizeStatus::kLocalized) return none;
    const std::vector<double> fine(options_.icp_gates.end() - 2, options_.icp_gates.end());
    const TreeIcpResult icp =
        TreeIcp(frame.query, frame.query_weights, local.points, *local.xy,
                ToPose4(answer.map_from_sensor), fine, options_.icp_iterations);
    return FromIcp(icp, frame, how);
  }

  void TryCloseLoop(StoredFrame& frame, int index, BuilderStep& step);
  void AddSequentialEdge(bool tracked);
  void Commit(StoredFrame frame, BuilderStep& step);
  void Remerge() { Remerge(options_.merge); }
  void Remerge(const MergeOptions& merge);  // every merged frame into a new map
  void NoteObservations(const std::vector<TreeObservation>& rows);

  MapBuilderOptions options_;
  std::unique_ptr<MergedMap> map_;
  std::vector<StoredFrame> frames_;
  std::vector<PoseGraphEdge> edges_;
  std::unordered_map<int64_t, int> first_frame_;  // tree id -> first frame index observing it
  PlanarEkf ekf_;
  Pose4 velocity_;  // last frame-to-frame motion, previous frame's body frame
  int failures_ = 0;
  int last_closure_ = -1000000;
  int pending_loop_index_ = -1;  // frame of an unconfirmed loop detection, -1 = none
  Eigen::Vector2d pending_loop_shift_ = Eigen::Vector2d::Zero();  // m, its correction
  int loop_closures_ = 0;
};

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

// Matches the frame against old trees only; a clear correction adds a loop edge, optimises the
// pose graph and re-merges every frame (this one included) with the corrected poses.
void MapBuilder::Impl::TryCloseLoop(StoredFrame& frame, int index, BuilderStep& step) {
  std::vector<TreeEstimate> old;
  for (const TreeEstimate& tree :
       map_->TreesNear(frame.pose.translation.head<2>(), options_.icp_range)) {
    const auto it = first_frame_.find(tree.id);
    if (it != first_frame_.end() && it->second <= index - options_.loop_min_age &&
        tree.status == TreeStatus::kConfirmed) {
      old.push_back(tree);
    }
  }
  if (static_cast<int>(old.size()) < options_.loop_min_old_trees) return;
  const LocalMap local = MakeLocalMap(old);
  TreeIcpResult icp =
      TreeIcp(frame.query, frame.query_weights, local.points, *local.xy, frame.pose,
              options_.icp_gates, options_.icp_iterations, options_.loop_yaw_search,
              local.variances);
  Fix fix = FromIcp(icp, frame, FrameFix::kTracked);
  fix.ok = fix.ok && icp.inliers >= options_.loop_min_inliers;
  if (!fix.ok && index % options_.loop_search_every == 0) {
    std::vector<MapTree> trees;
    for (const TreeEstimate& tree : old) trees.push_back(MapTree{tree.id, tree.position, tree.dbh});
    fix = Search(frame, trees, frame.pose, options_.loop_search_radius, FrameFix::kTracked);
    fix.ok = fix.ok && fix.inliers >= options_.loop_min_inliers;
    if (fix.ok) icp.matches = fix.matches;
  }
  if (!fix.ok) return;
  const double correction = (fix.pose.translation - frame.pose.translation).head<2>().norm();
  step.loop_correction = correction;
  if (correction < options_.loop_min_correction) return;
  // A real loop: the old trees fit the corrected pose clearly better than the tracked one
  // (a wrong match elsewhere would only equal it; on Oxford_Stein one such wrongly "closed"
  // the last frame and tore the map apart).
  const int tracked_inliers =
      TreeIcp(frame.query, frame.query_weights, local.points, *local.xy, frame.pose,
              {options_.icp_gates.back()}, 0, 0.0)
          .inliers;
  if (fix.inliers < options_.loop_min_gain * tracked_inliers) return;
  // ... and a second frame within loop_confirm_frames must see the same correction: a single
  // frame can be mis-tracked itself, and a false closure bends the whole trajectory.
  const Eigen::Vector2d shift = (fix.pose.translation - frame.pose.translation).head<2>();
  const bool confirmed = pending_loop_index_ >= 0 &&
                         index - pending_loop_index_ <= options_.loop_confirm_frames &&
                         (shift - pending_loop_shift_).norm() <= options_.loop_confirm_distance;
  pending_loop_index_ = index;
  pending_loop_shift_ = shift;
  if (!confirmed) return;
  pending_loop_index_ = -1;
  // Anchor: the earliest-mapping frame most of the matched old trees share.
  std::map<int, int> votes;
  for (const auto& [q, m] : fix.matches) ++votes[first_frame_[local.ids[m]]];
  int anchor = 0, best = -1;
  for (const auto& [f, n] : votes) {
    if (n > best) anchor = f, best = n;
  }
  // The tracked pose stays this frame's pose in the sequential edge; the loop edge says where
  // the old trees put it relative to the anchor frame.
  frames_.push_back(frame);
  AddSequentialEdge(/*tracked=*/true);
  frames_.pop_back();
  PoseGraphEdge loop;
  loop.from = anchor;
  loop.to = index;
  loop.measurement = Between(frames_[anchor].pose, fix.pose);
  loop.sigma = Eigen::Vector4d(options_.measurement_sigma_xy, options_.measurement_sigma_xy,
                               options_.measurement_sigma_xy, options_.measurement_sigma_yaw);
  loop.robust = true;
  edges_.push_back(loop);
  std::vector<Pose4> poses;
  for (const StoredFrame& f : frames_) poses.push_back(f.pose);
  poses.push_back(frame.pose);
  const PoseGraphResult optimized = OptimizePoseGraph(poses, edges_, 0, options_.pose_graph);
  for (size_t i = 0; i < frames_.size(); ++i) frames_[i].pose = optimized.poses[i];
  frame.pose = optimized.poses.back();
  ekf_.Reset(frame.pose, options_.measurement_sigma_xy, options_.measurement_sigma_yaw);
  step.loop_closed = true;
  last_closure_ = index;
  ++loop_closures_;
  frame.merged = true;
  frames_.push_back(frame);
  Remerge();
  frames_.pop_back();  // Commit pushes it again (without merging a second time)
}

MapBuilder::MapBuilder(const MapBuilderOptions& options)
    : impl_(std::make_unique<Impl>(options)) {}
MapBuilder::~MapBuilder() = default;
BuilderStep MapBuilder::AddFrame(const BuilderFrame& frame) { return impl_->AddFrame(frame); }
void MapBuilder::Finish() { impl_->Finish(); }
std::vector<Pose3> MapBuilder::Poses() const { return impl_->Poses(); }
const MergedMap& MapBuilder::map() const { return impl_->map(); }
std::vector<MapTree> MapBuilder::ConfirmedTrees() const { return map().ConfirmedMapTrees(); }
int MapBuilder::loop_closures() const { return impl_->loop_closures(); }
int MapBuilder::frames() const { return impl_->frames(); }

}  // namespace forestmap::algorithms
