// Landmark bundle adjustment (algorithms/mapping/tree_adjustment.h) against a known trajectory and
// forest: drifted starting poses, noisy detections, wrong associations and frames whose stem
// heights are off by metres.

#include "algorithms/mapping/tree_adjustment.h"

#include <gtest/gtest.h>

#include <random>

namespace forestmap::algorithms {
namespace {

constexpr double kRange = 25.0;           // m, detection range
constexpr double kNoise = 0.05;           // m, detection noise (1-sigma per axis)
constexpr double kPoseTolerance = 0.05;   // m, recovered horizontal positions vs truth
constexpr double kHeightTolerance = 0.1;  // m, recovered heights (stem heights are 2x noisier)

struct Scene {
  std::vector<Pose4> truth, start;
  std::vector<Eigen::Vector3d> trees, tree_start;
  std::vector<TreeAdjustmentObservation> observations;
};

// A 200 m walk with turns over rolling ground through 1500 trees (~110 within range), and a start
// that drifted (heading 0.2 deg and height 3 cm per frame, like frame-to-map tracking).
Scene MakeScene(double outlier_fraction, int biased_frames) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, kNoise);
  std::uniform_real_distribution<double> uniform(0, 1);
  Scene scene;
  Pose4 pose;
  for (int i = 0; i < 100; ++i) {
    pose.yaw = 0.4 * std::sin(i / 15.0);
    if (i > 0)
      pose.translation += Eigen::Vector3d(2 * std::cos(pose.yaw), 2 * std::sin(pose.yaw), 0);
    pose.translation.z() = 3 * std::sin(i / 20.0);
    scene.truth.push_back(pose);
  }
  for (int j = 0; j < 1500; ++j) {
    const double x = -20 + 230 * uniform(rng), y = -40 + 120 * uniform(rng);
    scene.trees.emplace_back(x, y, 2 * std::sin(x / 30.0) - 1.5);
  }
  Pose4 drifted = scene.truth[0];
  for (size_t i = 0; i < scene.truth.size(); ++i) {
    if (i > 0) {
      Pose4 step = Between(scene.truth[i - 1], scene.truth[i]);
      step.yaw += 0.0035;
      step.translation.z() += 0.03;
      drifted = Compose(drifted, step);
    }
    scene.start.push_back(drifted);
  }
  scene.tree_start.assign(scene.trees.size(), Eigen::Vector3d::Constant(kUnknown));
  for (size_t i = 0; i < scene.truth.size(); ++i) {
    const Pose4& p = scene.truth[i];
    const double bias = static_cast<int>(i) >= 40 && static_cast<int>(i) < 40 + biased_frames
                            ? -8.0
                            : 0.0;  // m, this frame's stem heights are off
    for (size_t j = 0; j < scene.trees.size(); ++j) {
      const Eigen::Vector3d d = scene.trees[j] - p.translation;
      if (d.head<2>().norm() > kRange) continue;
      TreeAdjustmentObservation o;
      o.frame = static_cast<int>(i);
      o.tree = static_cast<int>(j);
      const double c = std::cos(p.yaw), s = std::sin(p.yaw);
      o.level_position =
          Eigen::Vector3d(c * d.x() + s * d.y() + noise(rng), -s * d.x() + c * d.y() + noise(rng),
                          d.z() + 2 * noise(rng) + bias);
      if (uniform(rng) < outlier_fraction) o.level_position.head<2>() += Eigen::Vector2d(1.5, -1);
      o.weight_xy = 1 / (kNoise * kNoise);
      o.weight_z = 1 / (4 * kNoise * kNoise);
      scene.observations.push_back(o);
      if (!scene.tree_start[j].allFinite()) {  // where the drifted pose first put it
        const Pose4& q = scene.start[i];
        const double cq = std::cos(q.yaw), sq = std::sin(q.yaw);
        const Eigen::Vector3d& l = o.level_position;
        scene.tree_start[j] = q.translation + Eigen::Vector3d(cq * l.x() - sq * l.y(),
                                                              sq * l.x() + cq * l.y(), l.z());
      }
    }
  }
  for (Eigen::Vector3d& tree : scene.tree_start) {
    if (!tree.allFinite()) tree.setZero();
  }
  return scene;
}

double MaxError(const std::vector<Pose4>& poses, const std::vector<Pose4>& truth, bool height) {
  double worst = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Vector3d d = poses[i].translation - truth[i].translation;
    worst = std::max(worst, height ? std::abs(d.z()) : d.head<2>().norm());
  }
  return worst;
}

TEST(TreeAdjustment, RecoversDriftedPosesAndTreesInThreeDimensions) {
  const Scene scene = MakeScene(0.0, 0);
  ASSERT_GT(MaxError(scene.start, scene.truth, false), 3.0);
  ASSERT_GT(MaxError(scene.start, scene.truth, true), 2.0);
  const TreeAdjustmentResult result =
      AdjustTrees(scene.start, scene.tree_start, scene.observations);
  EXPECT_LT(MaxError(result.poses, scene.truth, false), kPoseTolerance);
  EXPECT_LT(MaxError(result.poses, scene.truth, true), kHeightTolerance);
  EXPECT_LT(result.final_rms, 2 * kNoise);
  EXPECT_LT(result.final_cost, result.initial_cost);
  double worst_tree = 0;
  for (size_t j = 0; j < scene.trees.size(); ++j) {
    if (scene.tree_start[j].isZero()) continue;  // never seen
    worst_tree = std::max(worst_tree, (result.trees[j] - scene.trees[j]).head<2>().norm());
  }
  EXPECT_LT(worst_tree, 3 * kPoseTolerance);
}

TEST(TreeAdjustment, WrongAssociationsPullWithBoundedForceAndBiasedHeightsStayInTheirFrames) {
  // 3% of the detections associated with the wrong tree (1.8 m off, all the same way), which
  // the Cauchy steps reject, and 5 consecutive frames whose stem heights are all 8 m low: those
  // frames' apparent heights take the bias, the trees' heights do not, and SmoothHeights gives
  // the sensor its true height back.
  const Scene scene = MakeScene(0.03, 5);
  TreeAdjustmentOptions options;
  options.cauchy_iterations = 10;
  options.iterations = 20;
  const TreeAdjustmentResult result =
      AdjustTrees(scene.start, scene.tree_start, scene.observations, {}, options);
  EXPECT_LT(MaxError(result.poses, scene.truth, false), kPoseTolerance);
  double worst_tree_height = 0;
  for (size_t j = 0; j < scene.trees.size(); ++j) {
    if (scene.tree_start[j].isZero()) continue;
    worst_tree_height =
        std::max(worst_tree_height, std::abs(result.trees[j].z() - scene.trees[j].z()));
  }
  EXPECT_LT(worst_tree_height, 2 * kHeightTolerance);
  std::vector<double> apparent;
  for (const Pose4& pose : result.poses) apparent.push_back(pose.translation.z());
  EXPECT_GT(std::abs(apparent[42] - scene.truth[42].translation.z()), 7.0);
  const std::vector<double> heights = SmoothHeights(apparent, 0.2, 0.3);
  double worst_height = 0;
  for (size_t i = 0; i < heights.size(); ++i) {
    worst_height = std::max(worst_height, std::abs(heights[i] - scene.truth[i].translation.z()));
  }
  EXPECT_LT(worst_height, 2 * kHeightTolerance);
}

TEST(TreeAdjustment, RejectsInvalidInput) {
  TreeAdjustmentObservation o;
  o.frame = 3;
  EXPECT_THROW(AdjustTrees({Pose4{}}, {Eigen::Vector3d::Zero()}, {o}), std::invalid_argument);
  TreeAdjustmentOptions options;
  options.huber_xy = 0;
  EXPECT_THROW(AdjustTrees({}, {}, {}, {}, options), std::invalid_argument);
  EXPECT_THROW(SmoothHeights({1.0}, 0.0, 0.3), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
