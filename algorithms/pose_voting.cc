#include "algorithms/pose_voting.h"

#include <algorithm>
#include <cmath>

namespace forestmap::algorithms {
namespace {

// Sensor pose cell for voting: 2 m x 2 m x ~6 deg.
uint64_t CellKey(const Rigid2& pose) {
  const int64_t cx = static_cast<int64_t>(std::floor(pose.translation.x() / 2.0));
  const int64_t cy = static_cast<int64_t>(std::floor(pose.translation.y() / 2.0));
  const int64_t cyaw = static_cast<int64_t>(std::floor((pose.yaw + M_PI) / 0.1));
  return (static_cast<uint64_t>(cx & 0xFFFFFF) << 40) |
         (static_cast<uint64_t>(cy & 0xFFFFFF) << 16) | static_cast<uint64_t>(cyaw & 0xFFFF);
}

}  // namespace

void PoseVoter::Add(const Triangle& qt) {
  // Per-side tolerance: search the ball that contains the box, then check each side.
  m_.triangle_keys->Radius(qt.sides, static_cast<float>(tol_ * std::sqrt(3.0)), found_);
  const uint32_t a = qt.vertex[0], b = qt.vertex[1], c = qt.vertex[2];
  // The canonical labels come from sorted side lengths; where two sides are within the
  // tolerance, noise may have swapped them in the map, so the swapped labelling votes as well.
  std::vector<TriangleFrame> frames = {FrameOf(seed_xy_[a], seed_xy_[b], seed_xy_[c])};
  if (qt.sides[1] - qt.sides[0] < tol_) frames.push_back(FrameOf(seed_xy_[b], seed_xy_[a], seed_xy_[c]));
  if (qt.sides[2] - qt.sides[1] < tol_) frames.push_back(FrameOf(seed_xy_[a], seed_xy_[c], seed_xy_[b]));
  const uint64_t mask = (uint64_t{1} << a) | (uint64_t{1} << b) | (uint64_t{1} << c);
  for (auto [t, d2] : found_) {
    const auto& key = m_.triangle_keys->point(t);
    if (std::abs(key[0] - qt.sides[0]) > tol_ || std::abs(key[1] - qt.sides[1]) > tol_ ||
        std::abs(key[2] - qt.sides[2]) > tol_) {
      continue;
    }
    const TriangleFrame& mf = m_.triangle_frames[t];
    for (const TriangleFrame& qf : frames) {
      if (qf.turn() * mf.turn() < 0) continue;  // mirror image: no rigid motion maps it
      // map = R(yaw) * query + t, with the long sides and the centroids aligned.
      Rigid2 pose;
      pose.yaw = WrapAngle(mf.heading() - qf.heading());
      const double cy = std::cos(pose.yaw), sy = std::sin(pose.yaw);
      pose.translation = {mf.cx - (cy * qf.cx - sy * qf.cy), mf.cy - (sy * qf.cx + cy * qf.cy)};
      if (prior_ && (pose.translation - prior_xy_).norm() > prior_->radius) continue;
      votes_.push_back({CellKey(pose), mask, static_cast<float>(pose.yaw),
                        static_cast<float>(pose.translation.x()),
                        static_cast<float>(pose.translation.y())});
    }
  }
}

std::vector<Hypothesis> PoseVoter::Best(int min_votes, size_t max) {
  // Votes before sorted_ are already in cell order: sort the new ones and merge.
  auto by_cell = [](const Vote& a, const Vote& b) { return a.cell < b.cell; };
  std::sort(votes_.begin() + sorted_, votes_.end(), by_cell);
  std::inplace_merge(votes_.begin(), votes_.begin() + sorted_, votes_.end(), by_cell);
  sorted_ = votes_.size();
  std::vector<Hypothesis> hypotheses;
  for (size_t begin = 0, end = 0; begin < votes_.size(); begin = end) {
    uint64_t mask = 0;
    double c = 0, s = 0;
    Eigen::Vector2d t = Eigen::Vector2d::Zero();
    for (end = begin; end < votes_.size() && votes_[end].cell == votes_[begin].cell; ++end) {
      mask |= votes_[end].seeds;
      c += std::cos(votes_[end].yaw);
      s += std::sin(votes_[end].yaw);
      t += Eigen::Vector2d(votes_[end].x, votes_[end].y);
    }
    Hypothesis h;
    h.votes = __builtin_popcountll(mask);
    if (h.votes < min_votes) continue;
    h.pose.yaw = std::atan2(s, c);
    h.pose.translation = t / static_cast<double>(end - begin);
    hypotheses.push_back(h);
  }
  const size_t keep = std::min(hypotheses.size(), max);
  std::partial_sort(hypotheses.begin(), hypotheses.begin() + keep, hypotheses.end(),
                    [](const Hypothesis& a, const Hypothesis& b) { return a.votes > b.votes; });
  hypotheses.resize(keep);
  return hypotheses;
}

}  // namespace forestmap::algorithms
