// MergedMap's change tracking: evidence of absence per tree, removal and restoring.

#include <algorithm>

#include "algorithms/merging/merged_map.h"

namespace forestmap::algorithms {

void MergedMap::Erase(int64_t id) {
  const auto cell = cell_of_.find(id);
  if (cell == cell_of_.end()) return;
  std::vector<int64_t>& ids = cells_[cell->second];
  ids.erase(std::find(ids.begin(), ids.end(), id));
  cell_of_.erase(cell);
  trees_.erase(id);
}

void MergedMap::Remove(int64_t id, int64_t time) {
  RemovedTree removed;
  removed.tree = trees_.at(id);
  removed.time = time;
  removed.evidence = evidence_[id];
  std::vector<TreeObservation> kept;
  kept.reserve(observations_.size());
  for (TreeObservation& row : observations_) {
    (row.tree_id == id ? removed.rows : kept).push_back(std::move(row));
  }
  observations_ = std::move(kept);
  Erase(id);
  removed_[id] = std::move(removed);
}

bool MergedMap::Restore(int64_t id) {
  const auto it = removed_.find(id);
  if (it == removed_.end()) return false;
  Put(it->second.tree);
  observations_.insert(observations_.end(), it->second.rows.begin(), it->second.rows.end());
  evidence_[id] = TreeEvidence{};
  removed_.erase(it);
  return true;
}

const TreeEvidence* MergedMap::EvidenceOf(int64_t id) const {
  const auto it = evidence_.find(id);
  if (it != evidence_.end()) return &it->second;
  const auto removed = removed_.find(id);
  return removed == removed_.end() ? nullptr : &removed->second.evidence;
}

AbsenceOptions MergedMap::LearnSource(const std::string& source, const AbsenceResult& frame) {
  SensorPool& pool = sensors_[source];
  pool.Add(frame);
  return pool.Apply(changes_.absence);
}

MergedMap::NearbyTrees MergedMap::Nearby(const Eigen::Vector2d& sensor_xy) const {
  NearbyTrees near;
  near.trees = TreesNear(sensor_xy, options_.max_range + 2 * options_.gate_distance);
  std::stable_partition(near.trees.begin(), near.trees.end(), [](const TreeEstimate& tree) {
    return tree.status == TreeStatus::kConfirmed;
  });
  for (const TreeEstimate& tree : near.trees) {
    const bool is_confirmed = tree.status == TreeStatus::kConfirmed;
    (is_confirmed ? near.confirmed : near.candidates).push_back({tree.id, tree.position, tree.dbh});
    if (!is_confirmed) continue;
    const auto evidence = evidence_.find(tree.id);
    near.standing.push_back(evidence != evidence_.end() && evidence->second.sightings > 0);
  }
  return near;
}

void MergedMap::LookBack(const std::string& source, const std::vector<TreeEstimate>& fresh,
                         const AbsenceOptions& options, std::vector<int64_t>& removed) {
  const auto views = views_.find(source);
  if (fresh.empty() || views == views_.end()) return;
  for (const PastView& view : views->second) {
    const Eigen::Vector2d sensor_xy = view.observation.map_from_sensor.translation().head<2>();
    std::vector<MapTree> reach;
    for (const TreeEstimate& tree : fresh) {
      if (!trees_.count(tree.id)) continue;  // retired by an earlier view
      if ((tree.position.head<2>() - sensor_xy).norm() <= options.range) {
        reach.push_back({tree.id, tree.position, tree.dbh});
      }
    }
    if (reach.empty()) continue;
    const NearbyTrees near = Nearby(sensor_xy);
    const AbsenceResult absence =
        ExpectTrees(near.confirmed, near.standing, reach, view.observation, options);
    for (size_t j = 0; j < reach.size(); ++j) {
      const TreeVisibility& visibility = absence.trees[near.confirmed.size() + j];
      if (AddView(evidence_[visibility.id], visibility, /*candidate=*/true, source, view.frame_id,
                  view.time, changes_.evidence)) {
        removed.push_back(visibility.id);
        Remove(visibility.id, view.time);
      }
    }
  }
}

ObserveResult MergedMap::Observe(const TimedFrame& timed) {
  const FrameObservations& frame = timed.frame;
  const Eigen::Vector2d sensor_xy = frame.map_from_sensor.translation().head<2>();
  const NearbyTrees near = Nearby(sensor_xy);
  const std::vector<TreeEstimate>& nearby = near.trees;
  AbsenceObservation observation;
  observation.map_from_sensor = frame.map_from_sensor;
  observation.pose_sigma_xy = timed.pose_sigma_xy;
  observation.pose_sigma_yaw = timed.pose_sigma_yaw;
  observation.trees = frame.trees;
  ObserveResult result;
  // What the frame teaches about its sensor, then the classification with the source's pooled
  // model (a frame over a clear-cut, which detects no map tree, uses what the source learned).
  result.absence =
      ExpectTrees(near.confirmed, near.standing, near.candidates, observation, changes_.absence);
  const AbsenceOptions source_options = LearnSource(frame.source, result.absence);
  if (source_options.range > 0 && source_options.detection_probability > 0) {
    result.absence =
        ExpectTrees(near.confirmed, near.standing, near.candidates, observation, source_options);
  }
  if (!frame.trees.empty()) result.merge = Merge(frame);
  for (size_t i = 0; i < nearby.size(); ++i) {
    const TreeVisibility& visibility = result.absence.trees[i];
    if (AddView(evidence_[visibility.id], visibility, nearby[i].status == TreeStatus::kCandidate,
                frame.source, frame.frame_id, timed.time, changes_.evidence)) {
      result.removed.push_back(visibility.id);
    }
  }
  // Trees this frame started were seen by it.
  for (const TreeEstimate& tree : result.merge.new_trees) {
    AddSighting(evidence_[tree.id], frame.source, timed.time);
  }
  for (int64_t id : result.removed) {
    if (trees_.count(id)) Remove(id, timed.time);
  }
  // The trees this frame started, against the source's earlier views of their places: within
  // one source (one pass, minutes) a stem does not appear, so the evidence runs both ways in
  // time; across sources only forward (a young tree was not there before).
  if (source_options.range > 0 && source_options.detection_probability > 0) {
    LookBack(frame.source, result.merge.new_trees, source_options, result.removed);
  }
  for (int64_t id : result.removed) evidence_.erase(id);
  views_[frame.source].push_back({frame.frame_id, timed.time, std::move(observation)});
  return result;
}

}  // namespace forestmap::algorithms
