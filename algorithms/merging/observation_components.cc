#include "algorithms/merging/observation_components.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace forestmap::algorithms {

ObservationLinker::ObservationLinker(double link_distance) : link_distance_(link_distance) {
  if (!(std::isfinite(link_distance) && link_distance > 0)) {
    throw std::invalid_argument("ObservationLinker: the link distance must be finite and > 0 m");
  }
}

int ObservationLinker::Add(const Eigen::Vector2d& xy) {
  const int index = static_cast<int>(xy_.size());
  xy_.push_back(xy);
  parent_.push_back(index);
  const auto cx = static_cast<int64_t>(std::floor(xy.x() / link_distance_));
  const auto cy = static_cast<int64_t>(std::floor(xy.y() / link_distance_));
  const double reach2 = link_distance_ * link_distance_;
  for (int64_t dx = -1; dx <= 1; ++dx) {
    for (int64_t dy = -1; dy <= 1; ++dy) {
      const auto cell = cells_.find(Key(cx + dx, cy + dy));
      if (cell == cells_.end()) continue;
      for (const int other : cell->second) {
        if ((xy_[other] - xy).squaredNorm() <= reach2) Link(index, other);
      }
    }
  }
  cells_[Key(cx, cy)].push_back(index);
  return index;
}

void ObservationLinker::Link(int a, int b) {
  a = Root(a), b = Root(b);
  if (a != b) parent_[std::max(a, b)] = std::min(a, b);  // a root is its component's first point
}

int ObservationLinker::Root(int index) {
  while (parent_[index] != index) index = parent_[index] = parent_[parent_[index]];
  return index;
}

std::vector<int> ObservationComponents(std::span<const TreeObservation> observations,
                                       const MergeOptions& options) {
  options.Check();
  ObservationLinker linker(options.gate_distance);
  for (const TreeObservation& row : observations) linker.Add(row.position.head<2>());
  // The root of a component is its smallest index: its first row.
  std::vector<int> component(observations.size(), -1);
  int count = 0;
  for (size_t r = 0; r < observations.size(); ++r) {
    const int root = linker.Root(static_cast<int>(r));
    component[r] = root == static_cast<int>(r) ? count++ : component[root];
  }
  return component;
}

}  // namespace forestmap::algorithms
