#pragma once

// Private to algorithms/mapping: the map builder's state, shared by map_builder.cc (frames,
// adjustment, merging), map_builder_search.cc (prediction and localisation of a frame) and
// map_builder_loops.cc (loop closure).

#include <map>
#include <memory>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "algorithms/core/kdtree.h"
#include "algorithms/mapping/map_builder.h"
#include "algorithms/mapping/planar_ekf.h"
#include "algorithms/mapping/tree_icp.h"

namespace forestmap::algorithms {

class MapBuilder::Impl {
 public:
  explicit Impl(const MapBuilderOptions& options)
      : options_(options), map_(std::make_unique<MergedMap>(options.merge)) {
    options_.Check();
  }

  BuilderStep AddFrame(const BuilderFrame& input);
  void Finish();

  // Joint planar adjustment of all poses and trees (tree_adjustment.h), then a re-merge with the
  // adjusted poses (associations follow the better poses).
  void Adjust();

  std::vector<Pose3> Poses() const;
  const MergedMap& map() const { return *map_; }
  int loop_closures() const { return loop_closures_; }
  int frames() const { return static_cast<int>(frames_.size()); }

 private:
  struct StoredFrame {
    int64_t frame_id = 0;
    Eigen::Matrix3d level_from_sensor = Eigen::Matrix3d::Identity();
    std::vector<DetectedTree> level_trees;  // levelled sensor frame
    std::vector<Eigen::Vector3d> query;     // levelled positions within icp_range
    std::vector<double> query_weights;
    std::vector<int> query_index;  // into level_trees
    Pose4 pose;                // map_from_level; z is the apparent height (where the stems put it)
    double height_offset = 0;  // m, apparent minus sensor height (this frame's stems' height bias)
    bool merged = false;
  };

  // Map trees near a place, with a k-d tree, for ICP.
  struct LocalMap {
    std::vector<Eigen::Vector3d> points;
    std::vector<double> variances;  // m^2, of each tree's mean position
    std::vector<int64_t> ids;
    std::unique_ptr<KdTree<double, 2>> xy;
  };
  static LocalMap MakeLocalMap(const std::vector<TreeEstimate>& trees);

  struct Fix {
    bool ok = false;
    FrameFix how = FrameFix::kTracked;
    Pose4 pose;
    int inliers = 0;
    double rmse = 0;
    double sigma_xy = 0, sigma_yaw = 0;
    std::vector<std::pair<int, int>> matches;  // (query index, local map index)
  };

  static Pose3 MapFromSensor(const StoredFrame& frame);
  StoredFrame Prepare(const BuilderFrame& input) const;
  Pose4 Predict(const BuilderFrame& input, const StoredFrame& previous);
  Fix FromIcp(const TreeIcpResult& icp, const StoredFrame& frame, FrameFix how) const;
  Fix Localize(const StoredFrame& frame, const Pose4& predicted);

  // Relocalize (optionally within `radius` of `prior`), then ICP from its answer.
  Fix Search(const StoredFrame& frame, std::vector<MapTree> trees,
             const std::optional<Pose4>& prior, double radius, FrameFix how) const;

  // Loop closure (map_builder_loops.cc): match the frame against old trees only; a clear,
  // confirmed correction adds a loop edge, optimises the pose graph and re-merges every frame.
  void TryCloseLoop(StoredFrame& frame, int index, BuilderStep& step);
  std::vector<TreeEstimate> OldTreesNear(const StoredFrame& frame, int index) const;
  Fix FindLoopFix(const StoredFrame& frame, int index, const LocalMap& local,
                  const std::vector<TreeEstimate>& old) const;
  bool ConfirmLoop(const StoredFrame& frame, int index, const LocalMap& local, const Fix& fix,
                   BuilderStep& step);
  void CloseLoop(StoredFrame& frame, int index, const LocalMap& local, const Fix& fix,
                 BuilderStep& step);
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

}  // namespace forestmap::algorithms
