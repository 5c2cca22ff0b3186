#pragma once
// An in-memory shared tree map fed frame by frame with MergeFrame (map_merge.h): what the
// server does with its store, for the map builder, benchmarks and tests. Keeps every
// observation row so that trees can be recomputed, consolidated or re-merged. Observe also
// weighs the evidence of absence (absence.h, absence_evidence.h) and removes trees that are gone:
// a removed tree leaves the live map (association, TreesNear, Trees, ConfirmedTrees) with its
// rows, and is kept with them, restorable.

#include <cstdint>
#include <map>
#include <string>
#include <unordered_map>
#include <vector>

#include "algorithms/merging/absence.h"
#include "algorithms/merging/absence_evidence.h"
#include "algorithms/merging/map_merge.h"

namespace forestmap::algorithms {

struct ChangeOptions {
  AbsenceOptions absence;
  AbsenceEvidenceOptions evidence;
};

// One observation for Observe: the frame, its pose's uncertainty and when it was made.
struct TimedFrame {
  FrameObservations frame;    // map_from_sensor: the pose
  double pose_sigma_xy = 0;   // m, 1-sigma per axis
  double pose_sigma_yaw = 0;  // rad, 1-sigma
  int64_t time = 0;           // caller's clock (e.g. seconds since the epoch)
};

struct ObserveResult {
  MergeResult merge;             // the detections' merge (empty for a frame without trees)
  AbsenceResult absence;         // which live trees near the sensor were seen or missed
  std::vector<int64_t> removed;  // trees removed by this frame's evidence
};

struct RemovedTree {
  TreeEstimate tree;
  std::vector<TreeObservation> rows;
  TreeEvidence evidence;  // as it stood when the tree was removed
  int64_t time = 0;       // of the observation that removed it
};

class MergedMap {
 public:
  explicit MergedMap(const MergeOptions& options = {}, const ChangeOptions& changes = {});

  // Adds surveyed trees as confirmed priors (their ids are kept; new trees get larger ids).
  void AddSurvey(const std::vector<MapTree>& trees);

  // Merges one frame with the trees near its sensor; new trees get fresh ids.
  MergeResult Merge(const FrameObservations& frame);

  // Weighs the frame's evidence of absence for the live trees near its sensor (candidates as
  // confirmed trees; the sensor's range learned from the frame, else from the source's earlier
  // frames, its detection rate pooled over the source's frames), merges its detections (Merge),
  // and removes every tree whose evidence reaches the threshold. A candidate's misses are grouped
  // by frame (its alternative, a false stem, is one frame's error), a confirmed tree's by source
  // (absence_evidence.h). The trees the frame starts are also weighed against the same source's
  // earlier views of their places (within one pass a stem does not appear; across sources the
  // evidence runs only forward in time: a young tree was not there before).
  ObserveResult Observe(const TimedFrame& frame);

  // Moves a removed tree and its rows back into the live map; false when `id` is not removed.
  bool Restore(int64_t id);

  const std::map<int64_t, RemovedTree>& removed() const { return removed_; }
  const TreeEvidence* EvidenceOf(int64_t id) const;  // nullptr: never observed

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
  void Erase(int64_t id);                 // from the live map and its grid
  void Remove(int64_t id, int64_t time);  // to removed_, with its rows
  struct NearbyTrees {
    std::vector<TreeEstimate> trees;  // confirmed first, then candidates
    std::vector<MapTree> confirmed, candidates;
    std::vector<char> standing;  // per confirmed tree: seen since the survey
  };
  NearbyTrees Nearby(const Eigen::Vector2d& sensor_xy) const;
  // Weighs the source's earlier views against the trees a frame of it just started.
  void LookBack(const std::string& source, const std::vector<TreeEstimate>& fresh,
                const AbsenceOptions& options, std::vector<int64_t>& removed);
  // Pools what `frame` teaches into its source's sensor model; the options to classify it with.
  AbsenceOptions LearnSource(const std::string& source, const AbsenceResult& frame);

  MergeOptions options_;
  ChangeOptions changes_;
  std::unordered_map<int64_t, TreeEvidence> evidence_;
  std::map<int64_t, RemovedTree> removed_;
  std::unordered_map<std::string, SensorPool> sensors_;
  struct PastView {
    int64_t frame_id = 0, time = 0;
    AbsenceObservation observation;
  };
  std::unordered_map<std::string, std::vector<PastView>> views_;  // per source, in order
  double cell_size_ = 10.0;                                       // m
  int64_t next_id_ = 1;
  std::unordered_map<int64_t, TreeEstimate> trees_;
  std::unordered_map<int64_t, CellKey> cell_of_;
  std::unordered_map<CellKey, std::vector<int64_t>> cells_;
  std::vector<TreeObservation> observations_;
};

}  // namespace forestmap::algorithms
