#pragma once
// An in-memory shared tree map fed frame by frame with MergeFrame (map_merge.h): what the
// server does with its store, for the map builder, benchmarks and tests. Keeps every
// observation row so that trees can be recomputed, consolidated or re-merged.

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "algorithms/merging/map_merge.h"

namespace forestmap::algorithms {

class MergedMap {
 public:
  explicit MergedMap(const MergeOptions& options = {});

  // Adds surveyed trees as confirmed priors (their ids are kept; new trees get larger ids).
  void AddSurvey(const std::vector<MapTree>& trees);

  // Merges one frame with the trees near its sensor; new trees get fresh ids.
  MergeResult Merge(const FrameObservations& frame);

  // Re-associates all observations and merges duplicates (ConsolidateTrees over the map).
  ConsolidateResult Consolidate();

  // Rebuilds every tree from the set of observations (RebuildTrees): the map a server holds
  // after any uploads of the same frames, in any order or batches.
  ConsolidateResult Rebuild();

  // Removes every observation of `source` and recomputes the affected trees.
  void RemoveSource(const std::string& source);

  // Trees within `radius` m (horizontally) of `center`, all statuses, by id.
  std::vector<TreeEstimate> TreesNear(const Eigen::Vector2d& center, double radius) const;

  std::vector<TreeEstimate> Trees() const;           // by id
  std::vector<TreeEstimate> ConfirmedTrees() const;  // by id
  std::vector<MapTree> ConfirmedMapTrees() const;    // by id, for relocalization
  const std::vector<TreeObservation>& observations() const { return observations_; }
  size_t size() const { return trees_.size(); }
  const MergeOptions& options() const { return options_; }

 private:
  using CellKey = int64_t;
  CellKey KeyOf(const Eigen::Vector2d& xy) const;
  void Put(const TreeEstimate& tree);  // inserts or updates, keeping the grid current
  void ReplaceTrees(const std::vector<TreeEstimate>& trees);

  MergeOptions options_;
  double cell_size_ = 10.0;  // m
  int64_t next_id_ = 1;
  std::unordered_map<int64_t, TreeEstimate> trees_;
  std::unordered_map<int64_t, CellKey> cell_of_;
  std::unordered_map<CellKey, std::vector<int64_t>> cells_;
  std::vector<TreeObservation> observations_;
};

}  // namespace forestmap::algorithms
