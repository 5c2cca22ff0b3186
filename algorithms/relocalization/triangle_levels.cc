#include "algorithms/relocalization/triangle_levels.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "algorithms/core/parallel.h"

namespace forestmap::algorithms {
namespace {

constexpr size_t kSpacingSample = 15;  // points of a cell whose spacing is measured

// Distance from `p` to its k-th nearest point of `kd` (not counting a point at p itself).
float KthDistance(const KdTree<float, 2>& kd, const KdTree<float, 2>::Point& p, size_t k) {
  const auto nn = kd.Knn(p, k + 1);
  return nn.empty() ? 0.f : std::sqrt(nn.back().second);
}

// Triangles of sides within [min_side, side] that point i is a vertex of, counted up to just
// past `limit` (the caller only asks whether they exceed it: a dense cell at too high a level
// has thousands).
size_t TrianglesAt(const KdTree<float, 2>& kd, uint32_t i, double side, double min_side,
                   size_t limit, std::vector<std::pair<uint32_t, float>>& found) {
  kd.Radius(kd.point(i), static_cast<float>(side), found);
  const float max2 = static_cast<float>(side * side),
              min2 = static_cast<float>(min_side * min_side);
  size_t count = 0;
  for (size_t a = 0; a < found.size() && count <= limit; ++a) {
    if (found[a].first == i || found[a].second < min2) continue;
    const auto& pa = kd.point(found[a].first);
    for (size_t b = a + 1; b < found.size(); ++b) {
      if (found[b].first == i || found[b].second < min2) continue;
      const auto& pb = kd.point(found[b].first);
      const float dx = pa[0] - pb[0], dy = pa[1] - pb[1];
      const float d2 = dx * dx + dy * dy;
      count += d2 >= min2 && d2 <= max2;
    }
  }
  return count;
}

}  // namespace

int TriangleLevels::count() const {
  if (max_side <= base_side) return 1;
  return 1 + static_cast<int>(std::ceil(std::log(max_side / base_side) / std::log(ratio) - 1e-9));
}

double TriangleLevels::Side(int level) const {
  return std::min(max_side, base_side * std::pow(ratio, level));
}

int TriangleLevels::LevelFor(double spacing) const {
  const double wanted = std::max(floor_side, scale * spacing);
  if (!(wanted > base_side)) return 0;
  const int level = static_cast<int>(std::lround(std::log(wanted / base_side) / std::log(ratio)));
  return std::clamp(level, 0, count() - 1);
}

SpacingCells::SpacingCells(const KdTree<float, 2>& kd, double cell, int threads)
    : threads_(threads) {
  const size_t n = kd.size();
  by_cell_.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    const auto& p = kd.point(i);
    const auto cx = static_cast<int64_t>(std::floor(p[0] / cell));
    const auto cy = static_cast<int64_t>(std::floor(p[1] / cell));
    by_cell_[i] = {
        (static_cast<uint64_t>(static_cast<uint32_t>(cx)) << 32) | static_cast<uint32_t>(cy), i};
  }
  std::sort(by_cell_.begin(), by_cell_.end());
  for (size_t i = 0; i < n; ++i) {
    if (i == 0 || by_cell_[i].first != by_cell_[i - 1].first) runs_.push_back(i);
  }
  runs_.push_back(n);
  spacing_.assign(runs_.size() - 1, 0.f);
  ParallelFor(spacing_.size(), threads_, [&](int, size_t first, size_t last) {
    std::vector<float> d;
    for (size_t r = first; r < last; ++r) {
      const size_t step = std::max<size_t>(1, (runs_[r + 1] - runs_[r]) / kSpacingSample);
      d.clear();
      for (size_t i = runs_[r]; i < runs_[r + 1]; i += step) {
        d.push_back(KthDistance(kd, kd.point(by_cell_[i].second), kSpacingNeighbour));
      }
      std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
      spacing_[r] = d[d.size() / 2];
    }
  });
  Smooth();
}

void SpacingCells::Smooth() {
  // Each cell's spacing becomes the median over it and its 8 neighbours: one stand, one level
  // (a patchwork of levels would keep only the triangles of the lower one across cells).
  std::unordered_map<uint64_t, float> by_key;
  for (size_t r = 0; r + 1 < runs_.size(); ++r) by_key[by_cell_[runs_[r]].first] = spacing_[r];
  std::vector<float> around;
  for (size_t r = 0; r + 1 < runs_.size(); ++r) {
    const uint64_t key = by_cell_[runs_[r]].first;
    const auto cx = static_cast<int32_t>(key >> 32), cy = static_cast<int32_t>(key & 0xFFFFFFFFu);
    around.clear();
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        const uint64_t k = (static_cast<uint64_t>(static_cast<uint32_t>(cx + dx)) << 32) |
                           static_cast<uint32_t>(cy + dy);
        const auto found = by_key.find(k);
        if (found != by_key.end()) around.push_back(found->second);
      }
    }
    std::nth_element(around.begin(), around.begin() + around.size() / 2, around.end());
    spacing_[r] = around[around.size() / 2];
  }
}

std::vector<float> SpacingCells::TreeSpacing() const {
  std::vector<float> spacing(by_cell_.size());
  for (size_t r = 0; r + 1 < runs_.size(); ++r) {
    for (size_t i = runs_[r]; i < runs_[r + 1]; ++i) spacing[by_cell_[i].second] = spacing_[r];
  }
  return spacing;
}

double SparseBudget::Factor(double spacing) const {
  if (!(spacing > spacing_from) || spacing_from <= 0) return 1.0;
  return std::min(max_factor, (spacing / spacing_from) * (spacing / spacing_from));
}

std::vector<uint8_t> SpacingCells::Levels(const KdTree<float, 2>& kd, const TriangleLevels& levels,
                                          double cap, const SparseBudget& sparse) const {
  std::vector<uint8_t> level(by_cell_.size(), 0);
  ParallelFor(spacing_.size(), threads_, [&](int, size_t first, size_t last) {
    std::vector<std::pair<uint32_t, float>> found;
    for (size_t r = first; r < last; ++r) {
      const size_t step = std::max<size_t>(1, (runs_[r + 1] - runs_[r]) / kSpacingSample);
      const size_t sampled = (runs_[r + 1] - runs_[r] + step - 1) / step;
      // A budget F times larger affords sides F^(1/4) times longer (a tree's triangles grow as
      // side^4 / spacing^4): a sparse stand's larger budget buys longer triangles.
      const double factor = sparse.Factor(spacing_[r]);
      int l = levels.LevelFor(spacing_[r] * std::sqrt(std::sqrt(factor)));
      const auto limit = static_cast<size_t>(3 * cap * factor * sampled);
      for (; l > 0; --l) {
        size_t triangles = 0;
        for (size_t i = runs_[r]; i < runs_[r + 1] && triangles <= limit; i += step) {
          triangles += TrianglesAt(kd, by_cell_[i].second, levels.Side(l), levels.min_side,
                                   limit - triangles, found);
        }
        if (triangles <= limit) break;
      }
      for (size_t i = runs_[r]; i < runs_[r + 1]; ++i) {
        level[by_cell_[i].second] = static_cast<uint8_t>(l);
      }
    }
  });
  return level;
}

double QuerySpacing(const std::vector<Eigen::Vector2d>& points, size_t count) {
  if (points.size() < 2) return 0.0;
  std::vector<double> spacing, d;
  for (size_t i = 0; i < std::min(count, points.size()); ++i) {
    d.clear();
    for (size_t j = 0; j < points.size(); ++j) {
      if (j != i) d.push_back((points[j] - points[i]).norm());
    }
    const size_t k = std::min<size_t>(kSpacingNeighbour, d.size()) - 1;
    std::nth_element(d.begin(), d.begin() + k, d.end());
    spacing.push_back(d[k]);
  }
  std::nth_element(spacing.begin(), spacing.begin() + spacing.size() / 2, spacing.end());
  return spacing[spacing.size() / 2];
}

std::vector<PageVector<Triangle>> EnumerateLevelled(const KdTree<float, 2>& kd,
                                                    const std::vector<Eigen::Vector2d>& points,
                                                    const std::vector<uint8_t>& level,
                                                    const TriangleLevels& levels, size_t begin,
                                                    size_t end) {
  std::vector<double> side2(levels.count());
  for (int l = 0; l < levels.count(); ++l) side2[l] = levels.Side(l) * levels.Side(l);
  const double min2 = levels.min_side * levels.min_side;
  std::vector<PageVector<Triangle>> out(levels.count());
  std::vector<std::pair<uint32_t, float>> found;
  std::vector<std::pair<uint32_t, double>> higher;  // neighbour, squared distance
  for (size_t i = begin; i < std::min(end, points.size()); ++i) {
    kd.Radius(kd.point(i), static_cast<float>(levels.Side(level[i]) + 1e-3), found);
    higher.clear();
    for (const auto& [j, unused] : found) {
      const double d2 = (points[j] - points[i]).squaredNorm();
      if (j > i && d2 >= min2 && d2 <= side2[std::min(level[i], level[j])])
        higher.push_back({j, d2});
    }
    for (size_t a = 0; a < higher.size(); ++a) {
      const auto [j, dij] = higher[a];
      for (size_t b = a + 1; b < higher.size(); ++b) {
        const auto [k, dik] = higher[b];
        const int l = std::min({level[i], level[j], level[k]});
        const double djk = (points[j] - points[k]).squaredNorm();
        const double longest2 = std::max({dij, dik, djk});
        if (djk < min2 || longest2 > side2[l]) continue;
        int band = 0;
        while (longest2 > side2[band]) ++band;
        out[band].push_back(MakeTriangle(points, static_cast<uint32_t>(i), j, k));
      }
    }
  }
  return out;
}

}  // namespace forestmap::algorithms
