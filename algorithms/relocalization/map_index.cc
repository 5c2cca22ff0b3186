#include "algorithms/relocalization/map_index.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "algorithms/core/parallel.h"
#include "algorithms/relocalization/map_index_internal.h"

namespace forestmap::algorithms {

namespace {

// Triangles per tree at these levels, from a sample of anchors (each triangle is counted at
// its smallest index, so the sample's mean scales to the whole map).
double TrianglesPerTree(const KdTree<float, 2>& kd, const std::vector<Eigen::Vector2d>& local,
                        const std::vector<uint8_t>& level, const TriangleLevels& levels) {
  const size_t step = std::max<size_t>(1, kd.size() / 2000);
  size_t triangles = 0, anchors = 0;
  for (size_t i = 0; i < kd.size(); i += step, ++anchors) {
    for (const auto& part : EnumerateLevelled(kd, local, level, levels, i, i + 1)) {
      triangles += part.size();
    }
  }
  return anchors ? static_cast<double>(triangles) / anchors : 0.0;
}

// The levels and every tree's level. A tree's side is what its local spacing suggests for
// target_neighbours (Poisson: pi density d_k^2 ~ k - 1/2), at least what a sparse query needs,
// lowered where its cell's trees would exceed the per-tree triangle budget (their count grows as
// side^4); small maps grow every side until the index holds min_index_triangles.
TriangleLevels ChooseLevels(const KdTree<float, 2>& kd, const std::vector<Eigen::Vector2d>& local,
                            const SpacingCells& cells, const MapIndexOptions& options,
                            std::vector<uint8_t>* level) {
  TriangleLevels levels;
  // Levels through min_triangle_side, down to 1 m (maps in odd units can be very dense).
  levels.floor_side = options.min_triangle_side;
  levels.ratio = options.level_ratio;
  levels.base_side = std::max(levels.min_side + 0.5, options.min_triangle_side);
  while (levels.base_side / levels.ratio >= levels.min_side + 0.5) levels.base_side /= levels.ratio;
  levels.max_side = options.max_triangle_side;
  levels.scale = std::sqrt(options.target_neighbours / (kSpacingNeighbour - 0.5));
  const bool large = kd.size() > options.large_map_trees;
  const double budget =
      large ? options.max_triangles_per_tree : options.small_map_triangles_per_tree;
  const double wanted =
      large ? 0.0 : std::min(budget, options.min_index_triangles / std::max<size_t>(1, kd.size()));
  constexpr int kIterations = 6;
  constexpr double kMaxScale = 100;  // every tree at the top level long before
  for (int i = 0; i < kIterations; ++i) {
    *level =
        cells.Levels(kd, levels, budget, {options.sparse_spacing, options.sparse_budget_factor});
    const double per_tree = std::max(0.1, TrianglesPerTree(kd, local, *level, levels));
    if (per_tree >= 0.8 * wanted || levels.scale > kMaxScale) break;
    levels.scale *= std::pow(wanted / per_tree, 0.25);
  }
  return levels;
}

// The levels' triangles, enumerated in parallel over chunks of anchor trees (small maps on the
// calling thread), one table per level.
void BuildTriangles(const std::vector<Eigen::Vector2d>& local, const SpacingCells& spacing,
                    const MapIndexOptions& options, MapIndexImpl& m) {
  const size_t n = local.size();
  const int chunks = n < 20000 ? 1 : ThreadCount(options.threads);
  std::vector<uint8_t> level;
  m.levels = ChooseLevels(*m.positions, local, spacing, options, &level);
  std::vector<std::vector<PageVector<Triangle>>> parts(chunks);
  ParallelFor(n, chunks, [&](int chunk, size_t begin, size_t end) {
    parts[chunk] = EnumerateLevelled(*m.positions, local, level, m.levels, begin, end);
  });
  m.tables.resize(m.levels.count());
  m.band_share.assign(m.levels.count(), 0.0);
  for (uint8_t l : level) {
    for (int b = 0; b <= l; ++b) m.band_share[b] += 1.0 / static_cast<double>(n);
  }
  PageVector<Triangle> all;
  for (int l = 0; l < m.levels.count(); ++l) {
    size_t total = 0;
    for (const auto& part : parts) total += part[l].size();
    if (total == 0) continue;
    all.clear();
    all.reserve(total);
    for (auto& part : parts) {
      all.insert(all.end(), part[l].begin(), part[l].end());
      PageVector<Triangle>().swap(part[l]);
    }
    m.tables[l] = std::make_unique<TriangleTable>(all, local, m.levels.Side(l));
  }
}

// Every coordinate finite and within kMaxIndexCoordinate (a z may be unknown, NaN): the float
// kd-tree and the occupancy grid's integer cells cannot represent more.
void CheckTreeRange(const std::vector<MapTree>& trees) {
  auto in_range = [](double v) { return std::abs(v) <= kMaxIndexCoordinate; };  // false for NaN
  for (size_t i = 0; i < trees.size(); ++i) {
    const Eigen::Vector3d& p = trees[i].position;
    if (!in_range(p.x()) || !in_range(p.y()) || !(std::isnan(p.z()) || in_range(p.z()))) {
      char where[96];
      std::snprintf(where, sizeof(where), "] (id %lld) at (%.6g, %.6g, %.6g)",
                    static_cast<long long>(trees[i].id), p.x(), p.y(), p.z());
      throw std::invalid_argument("MapIndex: trees[" + std::to_string(i) + where +
                                  " lies beyond the index range of 1e9 m or is not finite");
    }
  }
}

void CheckRingRange(const Ring& ring) {
  for (const Eigen::Vector2d& v : ring) {
    if (!(v.cwiseAbs().maxCoeff() <= kMaxIndexCoordinate)) {
      throw std::invalid_argument(
          "MapIndex: a boundary vertex lies beyond the index range of 1e9 m");
    }
  }
}

// The coverage: the boundary given (moved to kd coordinates), else the trees' alpha shape, each
// tree's disc of the inlier gate covered too.
void BuildCoverage(const std::vector<Eigen::Vector2d>& local, const SpacingCells& spacing,
                   std::vector<Polygon> boundary, const MapIndexOptions& options, MapIndexImpl& m) {
  m.coverage_derived = boundary.empty();
  std::vector<Polygon> kd;
  if (m.coverage_derived) {
    kd = DeriveCoverage(local, spacing.TreeSpacing(), options.coverage);
    m.coverage_outline = Translated(kd, m.origin);
  } else {
    kd = Translated(boundary, -m.origin);
    m.coverage_outline = std::move(boundary);
  }
  m.coverage = std::make_unique<CoverageGrid>(kd, local, options.coverage.tree_margin,
                                              options.coverage.resolution);
}

}  // namespace

void MapIndexOptions::Check() const {
  if (!(target_neighbours >= 2 && target_neighbours <= 50)) {
    throw std::invalid_argument("MapIndexOptions: target_neighbours must be in [2, 50]");
  }
  if (!(max_triangle_side > min_triangle_side + 0.5 && max_triangle_side <= kMaxTableSide)) {
    throw std::invalid_argument("MapIndexOptions: max_triangle_side must be in (min + 0.5, 32] m");
  }
  if (!(level_ratio >= 1.1 && level_ratio <= 4 && spacing_cell > 0)) {
    throw std::invalid_argument(
        "MapIndexOptions: level_ratio must be in [1.1, 4] and spacing_cell > 0");
  }
  if (!(min_triangle_side >= 0 && max_triangles_per_tree > 0 && small_map_triangles_per_tree > 0 &&
        min_index_triangles >= 0)) {
    throw std::invalid_argument("MapIndexOptions: min_triangle_side and triangle budget invalid");
  }
  if (!(occupancy_resolution > 0 && occupancy_radius >= occupancy_resolution)) {
    throw std::invalid_argument(
        "MapIndexOptions: need 0 < occupancy_resolution <= occupancy_radius");
  }
  if (!(sparse_spacing >= 0 && sparse_budget_factor >= 1)) {
    throw std::invalid_argument(
        "MapIndexOptions: need sparse_spacing >= 0 and sparse_budget_factor >= 1");
  }
  if (threads < 0) throw std::invalid_argument("MapIndexOptions: threads must be >= 0");
  coverage.Check();
}

MapIndex::MapIndex(std::vector<MapTree> trees, const MapIndexOptions& options,
                   std::vector<Polygon> boundary)
    : impl_(std::make_unique<MapIndexImpl>()) {
  options.Check();
  CheckTreeRange(trees);
  CheckPolygons(boundary);
  for (const Polygon& polygon : boundary) {
    CheckRingRange(polygon.outer);
    for (const Ring& hole : polygon.holes) CheckRingRange(hole);
  }
  MapIndexImpl& m = *impl_;
  m.trees = std::move(trees);
  const size_t n = m.trees.size();
  size_t with_z = 0, with_dbh = 0;
  for (const MapTree& t : m.trees) {
    m.origin += t.position.head<2>() / static_cast<double>(std::max<size_t>(n, 1));
    with_z += IsKnown(t.position.z());
    with_dbh += IsKnown(t.dbh);
  }
  m.has_z = n > 0 && with_z == n;
  m.has_dbh = n > 0 && with_dbh * 2 >= n;

  std::vector<KdTree<float, 2>::Point> xy(n);
  std::vector<Eigen::Vector2d> local(n);
  for (size_t i = 0; i < n; ++i) {
    local[i] = m.trees[i].position.head<2>() - m.origin;
    xy[i] = {static_cast<float>(local[i].x()), static_cast<float>(local[i].y())};
  }
  m.positions = std::make_unique<KdTree<float, 2>>(std::move(xy));
  const SpacingCells spacing(*m.positions, options.spacing_cell,
                             n < 20000 ? 1 : ThreadCount(options.threads));
  BuildTriangles(local, spacing, options, m);
  BuildCoverage(local, spacing, std::move(boundary), options, m);
  m.occupancy = std::make_unique<OccupancyGrid>(
      local, options.occupancy_radius, options.occupancy_resolution,
      [&m](double x0, double y0, double side) { return m.coverage->CoveredShare(x0, y0, side); });
  std::vector<Eigen::Vector2d>().swap(local);
#ifdef __GLIBC__
  // The build's buffers (triangles before they are tabled: 28 bytes each) are freed by now;
  // give their pages back rather than keep them in the heap.
  malloc_trim(0);
#endif
}

std::vector<Polygon> DerivedCoverage(const std::vector<MapTree>& trees,
                                     const MapIndexOptions& options) {
  options.Check();
  CheckTreeRange(trees);
  if (trees.empty()) return {};
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  for (const MapTree& t : trees) origin += t.position.head<2>() / static_cast<double>(trees.size());
  std::vector<Eigen::Vector2d> local(trees.size());
  std::vector<KdTree<float, 2>::Point> xy(trees.size());
  for (size_t i = 0; i < trees.size(); ++i) {
    local[i] = trees[i].position.head<2>() - origin;
    xy[i] = {static_cast<float>(local[i].x()), static_cast<float>(local[i].y())};
  }
  const KdTree<float, 2> kd(std::move(xy));
  const SpacingCells spacing(kd, options.spacing_cell, 1);
  return Translated(DeriveCoverage(local, spacing.TreeSpacing(), options.coverage), origin);
}

MapIndex::~MapIndex() = default;
size_t MapIndex::size() const { return impl_->trees.size(); }
const std::vector<Polygon>& MapIndex::coverage() const { return impl_->coverage_outline; }
bool MapIndex::Covers(const Eigen::Vector2d& map_xy) const {
  return impl_->Covered(map_xy - impl_->origin);
}
bool MapIndex::coverage_derived() const { return impl_->coverage_derived; }
double MapIndex::coverage_area() const { return impl_->coverage->area(); }
const std::vector<MapTree>& MapIndex::trees() const { return impl_->trees; }
bool MapIndex::has_z() const { return impl_->has_z; }
bool MapIndex::has_dbh() const { return impl_->has_dbh; }
double MapIndex::triangle_side() const {
  double side = 0;
  for (const auto& [level_side, count] : triangle_levels()) {
    if (count > 0) side = level_side;
  }
  return side;
}
size_t MapIndex::triangle_count() const {
  size_t count = 0;
  for (const auto& table : impl_->tables) count += table ? table->size() : 0;
  return count;
}
std::vector<std::pair<double, size_t>> MapIndex::triangle_levels() const {
  std::vector<std::pair<double, size_t>> out;
  for (size_t l = 0; l < impl_->tables.size(); ++l) {
    out.push_back(
        {impl_->levels.Side(static_cast<int>(l)), impl_->tables[l] ? impl_->tables[l]->size() : 0});
  }
  return out;
}
size_t MapIndex::MemoryBytes() const {
  const MapIndexImpl& m = *impl_;
  return sizeof(MapIndexImpl) + m.trees.capacity() * sizeof(MapTree) + m.positions->MemoryBytes() +
         m.occupancy->MemoryBytes() + m.coverage->MemoryBytes() + [&] {
           size_t bytes = 0;
           for (const auto& table : m.tables) bytes += table ? table->MemoryBytes() : 0;
           return bytes;
         }();
}

}  // namespace forestmap::algorithms
