#include "algorithms/relocalization/map_index.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>

#include "algorithms/core/parallel.h"
#include "algorithms/relocalization/map_index_internal.h"

namespace forestmap::algorithms {

namespace {

double MedianNearestNeighbourDistance(const KdTree<float, 2>& kd) {
  if (kd.size() < 2) return 1.0;
  std::vector<double> d;
  const size_t step = std::max<size_t>(1, kd.size() / 5000);
  for (size_t i = 0; i < kd.size(); i += step) {
    auto nn = kd.Knn(kd.point(i), 2);
    if (nn.size() == 2) d.push_back(std::sqrt(nn[1].second));
  }
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return std::max(0.3, d[d.size() / 2]);
}

// Triangles anchored at a sample of trees, per tree, for a given maximum side.
double TrianglesPerTree(const KdTree<float, 2>& kd, const std::vector<Eigen::Vector2d>& local,
                        const TriangleOptions& options) {
  const size_t step = std::max<size_t>(1, kd.size() / 2000);
  std::vector<std::vector<uint32_t>> neighbours(kd.size());
  std::vector<std::pair<uint32_t, float>> found;
  size_t anchors = 0;
  for (size_t i = 0; i < kd.size(); i += step, ++anchors) {
    kd.Radius(kd.point(i), static_cast<float>(options.max_side), found);
    for (auto& [j, d2] : found) neighbours[i].push_back(j);
  }
  // Each triangle is counted at its smallest index only: scale the sample to all anchors.
  size_t triangles = 0;
  for (size_t i = 0; i < kd.size(); i += step) {
    triangles += EnumerateTriangles(local, neighbours, options, i, i + 1).size();
  }
  return anchors ? static_cast<double>(triangles) / anchors : 0.0;
}

// Side length: what the map's density suggests, at least what a sparse query needs, and small
// enough for the index budget (triangle count grows as side^4).
double ChooseTriangleSide(const KdTree<float, 2>& kd, const std::vector<Eigen::Vector2d>& local,
                          const MapIndexOptions& options) {
  TriangleOptions tri;
  tri.max_side = std::max(
      options.min_triangle_side,
      TriangleSideForDensity(MedianNearestNeighbourDistance(kd), options.target_neighbours));
  const double budget = kd.size() > options.large_map_trees ? options.max_triangles_per_tree
                                                            : options.small_map_triangles_per_tree;
  const double wanted =
      std::min(budget, options.min_index_triangles / std::max<size_t>(1, kd.size()));
  for (int i = 0; i < 4; ++i) {
    const double per_tree = std::max(0.1, TrianglesPerTree(kd, local, tri));
    double target = per_tree > budget ? budget : (per_tree < 0.8 * wanted ? wanted : per_tree);
    if (target == per_tree) break;
    tri.max_side =
        std::min(options.max_triangle_side, tri.max_side * std::pow(target / per_tree, 0.25));
  }
  // Keep room above the shortest side allowed (maps in odd units can be very dense).
  return std::clamp(tri.max_side, tri.min_side + 0.5, options.max_triangle_side);
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

}  // namespace

void MapIndexOptions::Check() const {
  if (!(target_neighbours >= 2 && target_neighbours <= 50)) {
    throw std::invalid_argument("MapIndexOptions: target_neighbours must be in [2, 50]");
  }
  if (!(max_triangle_side > min_triangle_side + 0.5 && max_triangle_side < 60)) {
    throw std::invalid_argument("MapIndexOptions: max_triangle_side must be in (min + 0.5, 60) m");
  }
  if (!(min_triangle_side >= 0 && max_triangles_per_tree > 0 && small_map_triangles_per_tree > 0 &&
        min_index_triangles >= 0)) {
    throw std::invalid_argument("MapIndexOptions: min_triangle_side and triangle budget invalid");
  }
  if (!(occupancy_resolution > 0 && occupancy_radius >= occupancy_resolution)) {
    throw std::invalid_argument(
        "MapIndexOptions: need 0 < occupancy_resolution <= occupancy_radius");
  }
  if (threads < 0) throw std::invalid_argument("MapIndexOptions: threads must be >= 0");
}

MapIndex::MapIndex(std::vector<MapTree> trees, const MapIndexOptions& options)
    : impl_(std::make_unique<MapIndexImpl>()) {
  options.Check();
  CheckTreeRange(trees);
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
  m.triangle_options.max_side = ChooseTriangleSide(*m.positions, local, options);

  // Triangles, enumerated in parallel over chunks of anchor trees.
  // Small maps are built on the calling thread.
  const int chunks = n < 20000 ? 1 : ThreadCount(options.threads);
  std::vector<std::vector<Triangle>> parts(chunks);
  std::vector<std::vector<uint32_t>> neighbours(n);
  ParallelFor(n, chunks, [&](int, size_t begin, size_t end) {
    std::vector<std::pair<uint32_t, float>> found;
    for (size_t i = begin; i < end; ++i) {
      m.positions->Radius(m.positions->point(i), m.triangle_options.max_side, found);
      for (auto& [j, d2] : found) neighbours[i].push_back(j);
    }
  });
  ParallelFor(n, chunks, [&](int chunk, size_t begin, size_t end) {
    parts[chunk] = EnumerateTriangles(local, neighbours, m.triangle_options, begin, end);
  });
  neighbours = {};
  std::vector<Triangle> all;
  size_t total = 0;
  for (const auto& part : parts) total += part.size();
  all.reserve(total);
  for (auto& part : parts) {
    all.insert(all.end(), part.begin(), part.end());
    part = {};
  }
  m.triangles = std::make_unique<TriangleTable>(all, local, m.triangle_options.max_side);
  all = {};
  m.occupancy = std::make_unique<OccupancyGrid>(local, options.occupancy_radius,
                                                options.occupancy_resolution);
}

MapIndex::~MapIndex() = default;
size_t MapIndex::size() const { return impl_->trees.size(); }
const std::vector<MapTree>& MapIndex::trees() const { return impl_->trees; }
bool MapIndex::has_z() const { return impl_->has_z; }
bool MapIndex::has_dbh() const { return impl_->has_dbh; }
double MapIndex::triangle_side() const { return impl_->triangle_options.max_side; }
size_t MapIndex::triangle_count() const { return impl_->triangles->size(); }
size_t MapIndex::MemoryBytes() const {
  const MapIndexImpl& m = *impl_;
  return sizeof(MapIndexImpl) + m.trees.capacity() * sizeof(MapTree) + m.positions->MemoryBytes() +
         m.triangles->MemoryBytes() + m.occupancy->MemoryBytes();
}

}  // namespace forestmap::algorithms
