#include "algorithms/merging/merged_map.h"

#include <algorithm>
#include <cmath>

namespace forestmap::algorithms {

MergedMap::MergedMap(const MergeOptions& options, const ChangeOptions& changes)
    : options_(options), changes_(changes) {
  options_.Check();
  changes_.absence.Check();
  changes_.evidence.Check();
}

MergedMap::CellKey MergedMap::KeyOf(const Eigen::Vector2d& xy) const {
  const int64_t cx = static_cast<int64_t>(std::floor(xy.x() / cell_size_));
  const int64_t cy = static_cast<int64_t>(std::floor(xy.y() / cell_size_));
  return (cx << 32) ^ (cy & 0xffffffffLL);
}

void MergedMap::Put(const TreeEstimate& tree) {
  const CellKey key = KeyOf(tree.position.head<2>());
  const auto old = cell_of_.find(tree.id);
  if (old != cell_of_.end() && old->second != key) {
    std::vector<int64_t>& ids = cells_[old->second];
    ids.erase(std::find(ids.begin(), ids.end(), tree.id));
  }
  if (old == cell_of_.end() || old->second != key) cells_[key].push_back(tree.id);
  cell_of_[tree.id] = key;
  trees_[tree.id] = tree;
  next_id_ = std::max(next_id_, tree.id + 1);
}

void MergedMap::ReplaceTrees(const std::vector<TreeEstimate>& trees) {
  trees_.clear();
  cell_of_.clear();
  cells_.clear();
  for (const TreeEstimate& tree : trees) Put(tree);
}

void MergedMap::AddSurvey(const std::vector<MapTree>& trees) {
  for (const MapTree& tree : trees) {
    const TreeObservation row = SurveyObservation(tree, options_);
    const TreeObservation rows[] = {row};
    Put(EstimateFromObservations(tree.id, rows, options_));
    observations_.push_back(row);
  }
}

std::vector<TreeEstimate> MergedMap::TreesNear(const Eigen::Vector2d& center, double radius) const {
  std::vector<TreeEstimate> out;
  const int64_t x0 = static_cast<int64_t>(std::floor((center.x() - radius) / cell_size_));
  const int64_t x1 = static_cast<int64_t>(std::floor((center.x() + radius) / cell_size_));
  const int64_t y0 = static_cast<int64_t>(std::floor((center.y() - radius) / cell_size_));
  const int64_t y1 = static_cast<int64_t>(std::floor((center.y() + radius) / cell_size_));
  for (int64_t cx = x0; cx <= x1; ++cx) {
    for (int64_t cy = y0; cy <= y1; ++cy) {
      const auto it = cells_.find((cx << 32) ^ (cy & 0xffffffffLL));
      if (it == cells_.end()) continue;
      for (int64_t id : it->second) {
        const TreeEstimate& tree = trees_.at(id);
        if ((tree.position.head<2>() - center).norm() <= radius) out.push_back(tree);
      }
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return out;
}

MergeResult MergedMap::Merge(const FrameObservations& frame) {
  const std::vector<TreeEstimate> nearby =
      TreesNear(frame.map_from_sensor.translation().head<2>(),
                options_.max_range + 2 * options_.gate_distance);
  MergeResult result = MergeFrame(nearby, frame, options_);
  std::vector<int64_t> ids(result.new_trees.size());
  for (int64_t& id : ids) id = next_id_++;
  ResolveNewIds(result, ids);
  for (const TreeEstimate& tree : result.updated_trees) Put(tree);
  for (const TreeEstimate& tree : result.new_trees) Put(tree);
  observations_.insert(observations_.end(), result.observations.begin(), result.observations.end());
  return result;
}

ConsolidateResult MergedMap::Consolidate() {
  ConsolidateResult result = ConsolidateTrees(Trees(), observations_, options_);
  observations_ = result.observations;
  ReplaceTrees(result.trees);
  return result;
}

ConsolidateResult MergedMap::Rebuild() {
  ConsolidateResult result = RebuildTrees(Trees(), observations_, next_id_, options_);
  observations_ = result.observations;
  ReplaceTrees(result.trees);
  return result;
}

void MergedMap::RemoveSource(const std::string& source) {
  std::unordered_map<int64_t, std::vector<TreeObservation>> rows_of;
  std::vector<TreeObservation> kept;
  for (const TreeObservation& row : observations_) {
    if (row.source == source) {
      rows_of.try_emplace(row.tree_id);
    } else {
      kept.push_back(row);
    }
  }
  for (const TreeObservation& row : kept) {
    const auto it = rows_of.find(row.tree_id);
    if (it != rows_of.end()) it->second.push_back(row);
  }
  observations_ = std::move(kept);
  for (const auto& [id, rows] : rows_of) {
    if (rows.empty()) {
      Erase(id);
    } else {
      Put(EstimateFromObservations(id, rows, options_));
    }
  }
}

std::vector<TreeEstimate> MergedMap::Trees() const {
  std::vector<TreeEstimate> out;
  out.reserve(trees_.size());
  for (const auto& [id, tree] : trees_) out.push_back(tree);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return out;
}

std::vector<TreeEstimate> MergedMap::ConfirmedTrees() const {
  std::vector<TreeEstimate> out = Trees();
  std::erase_if(out, [](const TreeEstimate& t) { return t.status != TreeStatus::kConfirmed; });
  return out;
}

std::vector<MapTree> MergedMap::ConfirmedMapTrees() const {
  std::vector<MapTree> out;
  for (const TreeEstimate& tree : ConfirmedTrees()) {
    MapTree map_tree;
    map_tree.id = tree.id;
    map_tree.position = tree.position;
    map_tree.dbh = tree.dbh;
    out.push_back(map_tree);
  }
  return out;
}

}  // namespace forestmap::algorithms
