// Loop closure of the map builder: match a frame against trees mapped long ago, confirm the
// correction on a second frame, then add a loop edge, optimise the pose graph and re-merge.

#include <map>
#include <vector>

#include "algorithms/mapping/map_builder_internal.h"
#include "algorithms/mapping/pose_graph.h"

namespace forestmap::algorithms {

void MapBuilder::Impl::TryCloseLoop(StoredFrame& frame, int index, BuilderStep& step) {
  const std::vector<TreeEstimate> old = OldTreesNear(frame, index);
  if (static_cast<int>(old.size()) < options_.loop_min_old_trees) return;
  const LocalMap local = MakeLocalMap(old);
  const Fix fix = FindLoopFix(frame, index, local, old);
  if (!fix.ok) return;
  if (!ConfirmLoop(frame, index, local, fix, step)) return;
  CloseLoop(frame, index, local, fix, step);
}

// Confirmed trees near the frame first seen at least loop_min_age frames ago.
std::vector<TreeEstimate> MapBuilder::Impl::OldTreesNear(const StoredFrame& frame,
                                                         int index) const {
  std::vector<TreeEstimate> old;
  for (const TreeEstimate& tree :
       map_->TreesNear(frame.pose.translation.head<2>(), options_.icp_range)) {
    const auto it = first_frame_.find(tree.id);
    if (it != first_frame_.end() && it->second <= index - options_.loop_min_age &&
        tree.status == TreeStatus::kConfirmed) {
      old.push_back(tree);
    }
  }
  return old;
}

// ICP from the tracked pose with a yaw search; every loop_search_every frames a relocalization
// within loop_search_radius when ICP finds nothing.
MapBuilder::Impl::Fix MapBuilder::Impl::FindLoopFix(const StoredFrame& frame, int index,
                                                    const LocalMap& local,
                                                    const std::vector<TreeEstimate>& old) const {
  const TreeIcpResult icp = TreeIcp(frame.query, frame.query_weights, local.points, *local.xy,
                                    frame.pose, options_.icp_gates, options_.icp_iterations,
                                    options_.loop_yaw_search, local.variances);
  Fix fix = FromIcp(icp, frame, FrameFix::kTracked);
  fix.ok = fix.ok && icp.inliers >= options_.loop_min_inliers;
  if (!fix.ok && index % options_.loop_search_every == 0) {
    std::vector<MapTree> trees;
    for (const TreeEstimate& tree : old) trees.push_back(MapTree{tree.id, tree.position, tree.dbh});
    fix = Search(frame, trees, frame.pose, options_.loop_search_radius, FrameFix::kTracked);
    fix.ok = fix.ok && fix.inliers >= options_.loop_min_inliers;
  }
  return fix;
}

// Whether `fix` is a real loop: a large enough correction, a clear gain over the tracked pose,
// and the same correction seen by a second frame within loop_confirm_frames.
bool MapBuilder::Impl::ConfirmLoop(const StoredFrame& frame, int index, const LocalMap& local,
                                   const Fix& fix, BuilderStep& step) {
  const double correction = (fix.pose.translation - frame.pose.translation).head<2>().norm();
  step.loop_correction = correction;
  if (correction < options_.loop_min_correction) return false;
  // The old trees must fit the corrected pose clearly better than the tracked one (a wrong
  // match elsewhere would only equal it; on Oxford_Stein one such wrongly "closed" the last
  // frame and tore the map apart).
  const int tracked_inliers = TreeIcp(frame.query, frame.query_weights, local.points, *local.xy,
                                      frame.pose, {options_.icp_gates.back()}, 0, 0.0)
                                  .inliers;
  if (fix.inliers < options_.loop_min_gain * tracked_inliers) return false;
  // A single frame can be mis-tracked itself, and a false closure bends the whole trajectory.
  const Eigen::Vector2d shift = (fix.pose.translation - frame.pose.translation).head<2>();
  const bool confirmed = pending_loop_index_ >= 0 &&
                         index - pending_loop_index_ <= options_.loop_confirm_frames &&
                         (shift - pending_loop_shift_).norm() <= options_.loop_confirm_distance;
  pending_loop_index_ = index;
  pending_loop_shift_ = shift;
  if (!confirmed) return false;
  pending_loop_index_ = -1;
  return true;
}

// Adds the loop edge from the anchor frame (the earliest-mapping frame most of the matched old
// trees share), optimises the pose graph and re-merges every frame with the corrected poses.
void MapBuilder::Impl::CloseLoop(StoredFrame& frame, int index, const LocalMap& local,
                                 const Fix& fix, BuilderStep& step) {
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

}  // namespace forestmap::algorithms
