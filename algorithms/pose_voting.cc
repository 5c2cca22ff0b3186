#include "algorithms/pose_voting.h"

#include <algorithm>
#include <cmath>

namespace forestmap::algorithms {
namespace {

// Sensor pose cell for voting: 1.5 m x 1.5 m x 4 deg. Finer than the spread of the votes of a
// true pose would split them, coarser lets false votes pile up: 2 m x 6 deg cells ranked the
// true pose below 100 others in 6% of the Oxford_Stein frames.
constexpr double kCellSize = 1.5;  // m
constexpr double kCellYaw = 0.07;  // rad

uint64_t CellKey(const Rigid2& pose) {
  const int64_t cx = static_cast<int64_t>(std::floor(pose.translation.x() / kCellSize));
  const int64_t cy = static_cast<int64_t>(std::floor(pose.translation.y() / kCellSize));
  const int64_t cyaw = static_cast<int64_t>(std::floor((pose.yaw + M_PI) / kCellYaw));
  return (static_cast<uint64_t>(cx & 0xFFFFFF) << 40) |
         (static_cast<uint64_t>(cy & 0xFFFFFF) << 16) | static_cast<uint64_t>(cyaw & 0xFFFF);
}

constexpr uint64_t kEmpty = ~uint64_t{0};  // CellKey never makes it (yaw bits stay < 0xFFFF)

}  // namespace

PoseVoter::PoseVoter(const MapIndexImpl& m, const std::vector<Eigen::Vector2d>& seed_xy,
                     const std::optional<PriorPose>& prior, const Eigen::Vector2d& prior_xy,
                     double tolerance, int min_votes)
    : m_(m),
      seed_xy_(seed_xy),
      prior_(prior),
      prior_xy_(prior_xy),
      tol_(tolerance),
      min_votes_(min_votes),
      table_(4096, Cell{kEmpty}) {}

size_t PoseVoter::Probe(uint64_t key) const {
  const size_t mask = table_.size() - 1;
  size_t i = (key * 0x9E3779B97F4A7C15ull) >> 20 & mask;
  while (table_[i].key != key && table_[i].key != kEmpty) i = (i + 1) & mask;
  return i;
}

PoseVoter::Cell& PoseVoter::Slot(uint64_t key) {
  if (2 * (used_ + 1) > table_.size()) {  // keep the load under 1/2
    std::vector<Cell> old(2 * table_.size(), Cell{kEmpty});
    old.swap(table_);
    used_ = 0;
    for (const Cell& cell : old) {
      if (cell.key != kEmpty) Slot(cell.key) = cell;
    }
  }
  Cell& cell = table_[Probe(key)];
  if (cell.key == kEmpty) {
    ++used_;
    cell.key = key;
  }
  return cell;
}

void PoseVoter::Vote(uint64_t seeds, const Rigid2& pose, double cos_yaw, double sin_yaw) {
  Cell& cell = Slot(CellKey(pose));
  cell.seeds |= seeds;
  cell.cos += static_cast<float>(cos_yaw);
  cell.sin += static_cast<float>(sin_yaw);
  cell.x += static_cast<float>(pose.translation.x());
  cell.y += static_cast<float>(pose.translation.y());
  ++cell.votes;
  const int voters = __builtin_popcountll(cell.seeds);
  if (voters != cell.voters && voters >= min_votes_) by_voters_[voters].push_back(cell.key);
  cell.voters = voters;
}

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
      Vote(mask, pose, cy, sy);
    }
  }
}

std::vector<Hypothesis> PoseVoter::Best(size_t max) const {
  std::vector<Hypothesis> hypotheses;
  std::vector<uint64_t> level;
  for (int voters = 64; voters >= min_votes_ && hypotheses.size() < max; --voters) {
    level.clear();
    for (uint64_t key : by_voters_[voters]) {
      if (table_[Probe(key)].voters == voters) level.push_back(key);
    }
    std::sort(level.begin(), level.end());  // ties in cell order
    for (size_t i = 0; i < level.size() && hypotheses.size() < max; ++i) {
      const Cell& cell = table_[Probe(level[i])];
      Hypothesis h;
      h.votes = voters;
      h.pose.yaw = std::atan2(cell.sin, cell.cos);
      h.pose.translation = Eigen::Vector2d(cell.x, cell.y) / static_cast<double>(cell.votes);
      hypotheses.push_back(h);
    }
  }
  return hypotheses;
}

}  // namespace forestmap::algorithms
