#include "algorithms/detection/stem_clustering.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace forestmap::algorithms {
namespace {

constexpr int64_t kBias = int64_t{1} << 30;

uint64_t Key(int64_t ix, int64_t iy) {
  return (static_cast<uint64_t>(iy + kBias) << 32) | static_cast<uint64_t>(ix + kBias);
}

struct Cell {
  uint64_t key = 0;
  int64_t ix = 0, iy = 0;
  uint32_t begin = 0, end = 0;  // range in the sorted entries
  Eigen::Vector2f mean = Eigen::Vector2f::Zero();
};

}  // namespace

void StemLayerOptions::Check() const {
  if (!(max_height > min_height)) {
    throw std::invalid_argument("StemLayerOptions: max_height must be > min_height");
  }
}

void StemClusterOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("StemClusterOptions: ") + what);
  };
  require(eps > 0, "eps must be > 0");
  require(min_points >= 1, "min_points must be >= 1");
  require(min_cluster_points >= 1, "min_cluster_points must be >= 1");
  require(cell_fraction > 0 && cell_fraction <= 1, "cell_fraction must be in (0, 1]");
}

std::vector<uint32_t> ExtractStemLayer(std::span<const float> heights, bool ground_known,
                                       const StemLayerOptions& options) {
  options.Check();
  const float low = ground_known ? static_cast<float>(options.min_height) : 0.f;
  const float high = static_cast<float>(ground_known ? options.max_height
                                                     : options.max_height - options.min_height);
  std::vector<uint32_t> layer;
  for (size_t i = 0; i < heights.size(); ++i) {
    if (heights[i] >= low && heights[i] <= high) layer.push_back(static_cast<uint32_t>(i));
  }
  return layer;
}

namespace {

using Entry = std::pair<uint64_t, uint32_t>;  // cell key, point index

// The points in cells of side eps * cell_fraction: `entries` sorted by cell, one Cell per
// occupied cell (in key order) with its range of entries and its points' mean.
std::vector<Cell> GridCells(std::span<const Eigen::Vector3f> points,
                            std::span<const uint32_t> indices, double side,
                            std::vector<Entry>& entries) {
  entries.resize(indices.size());
  for (size_t k = 0; k < indices.size(); ++k) {
    const Eigen::Vector3f& p = points[indices[k]];
    entries[k] = {Key(static_cast<int64_t>(std::floor(p.x() / side)),
                      static_cast<int64_t>(std::floor(p.y() / side))),
                  indices[k]};
  }
  std::sort(entries.begin(), entries.end());
  std::vector<Cell> cells;
  for (uint32_t k = 0; k < entries.size();) {
    Cell cell;
    cell.key = entries[k].first;
    cell.ix = static_cast<int64_t>(cell.key & 0xffffffffu) - kBias;
    cell.iy = static_cast<int64_t>(cell.key >> 32) - kBias;
    cell.begin = k;
    while (k < entries.size() && entries[k].first == cell.key) {
      cell.mean += points[entries[k].second].head<2>();
      ++k;
    }
    cell.end = k;
    cell.mean /= static_cast<float>(cell.end - cell.begin);
    cells.push_back(cell);
  }
  return cells;
}

// Neighbour lists (cells within eps, by their means) as one flat array, and which cells are core
// cells (min_points points within eps).
struct Neighbours {
  std::vector<uint32_t> start;  // per cell, plus one past the end: its range in `list`
  std::vector<uint32_t> list;
  std::vector<uint8_t> core;
};

Neighbours FindNeighbours(const std::vector<Cell>& cells, int reach,
                          const StemClusterOptions& options) {
  const float eps2 = static_cast<float>(options.eps * options.eps);
  Neighbours n{std::vector<uint32_t>(cells.size() + 1, 0), {}, std::vector<uint8_t>(cells.size())};
  for (size_t c = 0; c < cells.size(); ++c) {
    uint32_t count = 0;
    for (int dy = -reach; dy <= reach; ++dy) {
      const uint64_t first = Key(cells[c].ix - reach, cells[c].iy + dy);
      const uint64_t last = Key(cells[c].ix + reach, cells[c].iy + dy);
      auto it = std::lower_bound(cells.begin(), cells.end(), first,
                                 [](const Cell& a, uint64_t key) { return a.key < key; });
      for (; it != cells.end() && it->key <= last; ++it) {
        if ((it->mean - cells[c].mean).squaredNorm() > eps2) continue;
        count += it->end - it->begin;
        n.list.push_back(static_cast<uint32_t>(it - cells.begin()));
      }
    }
    n.start[c + 1] = static_cast<uint32_t>(n.list.size());
    n.core[c] = count >= static_cast<uint32_t>(options.min_points);
  }
  return n;
}

// Connected components of core cells; border cells join the first cluster that reaches them.
// Returns the label per cell (-1: noise) and sets the cluster count.
std::vector<int32_t> LabelComponents(const Neighbours& n, int32_t* clusters) {
  std::vector<int32_t> label(n.core.size(), -1);
  std::vector<uint32_t> stack;
  int32_t next = 0;
  for (size_t seed = 0; seed < n.core.size(); ++seed) {
    if (!n.core[seed] || label[seed] >= 0) continue;
    label[seed] = next;
    stack.assign(1, static_cast<uint32_t>(seed));
    while (!stack.empty()) {
      const uint32_t c = stack.back();
      stack.pop_back();
      for (uint32_t k = n.start[c]; k < n.start[c + 1]; ++k) {
        const uint32_t other = n.list[k];
        if (label[other] >= 0) continue;
        label[other] = next;
        if (n.core[other]) stack.push_back(other);
      }
    }
    ++next;
  }
  *clusters = next;
  return label;
}

}  // namespace

StemClusters ClusterStems(std::span<const Eigen::Vector3f> points,
                          std::span<const uint32_t> indices, const StemClusterOptions& options) {
  options.Check();
  StemClusters result;
  if (indices.empty()) return result;
  const double side = options.eps * options.cell_fraction;
  const int reach = static_cast<int>(std::ceil(options.eps / side));
  std::vector<Entry> entries;
  const std::vector<Cell> cells = GridCells(points, indices, side, entries);
  result.cells = cells.size();
  int32_t next = 0;
  const std::vector<int32_t> label = LabelComponents(FindNeighbours(cells, reach, options), &next);
  std::vector<std::vector<uint32_t>> clusters(next);
  for (size_t c = 0; c < cells.size(); ++c) {
    if (label[c] < 0) {
      result.noise_points += cells[c].end - cells[c].begin;
      continue;
    }
    for (uint32_t k = cells[c].begin; k < cells[c].end; ++k) {
      clusters[label[c]].push_back(entries[k].second);
    }
  }
  for (auto& cluster : clusters) {
    if (cluster.size() < static_cast<size_t>(options.min_cluster_points)) {
      result.noise_points += cluster.size();
    } else {
      result.clusters.push_back(std::move(cluster));
    }
  }
  return result;
}

}  // namespace forestmap::algorithms
