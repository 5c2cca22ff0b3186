#pragma once
// The one wrapper around nanoflann (Debian ships 1.4.3: SearchParams, std::pair results).
// A static k-d tree over a contiguous array of fixed-dimension float or double points.

#include <array>
#include <cstdint>
#include <limits>
#include <nanoflann.hpp>
#include <utility>
#include <vector>

namespace forestmap::algorithms {

template <typename Scalar, int kDim>
class KdTree {
 public:
  using Point = std::array<Scalar, kDim>;

  explicit KdTree(std::vector<Point> points, int leaf_size = 16)
      : points_{std::move(points)},
        index_(kDim, points_, nanoflann::KDTreeSingleIndexAdaptorParams(leaf_size)) {
    if (!points_.points.empty()) index_.buildIndex();
  }
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  size_t size() const { return points_.points.size(); }
  const Point& point(size_t i) const { return points_.points[i]; }

  // Nearest point; returns {index, squared distance} or {-1, inf} when empty.
  std::pair<int64_t, Scalar> Nearest(const Point& query) const {
    if (size() == 0) return {-1, std::numeric_limits<Scalar>::infinity()};
    uint32_t index = 0;
    Scalar dist2 = 0;
    index_.knnSearch(query.data(), 1, &index, &dist2);
    return {static_cast<int64_t>(index), dist2};
  }

  // k nearest points, closest first: {index, squared distance}.
  std::vector<std::pair<uint32_t, Scalar>> Knn(const Point& query, size_t k) const {
    k = std::min(k, size());
    if (k == 0) return {};
    std::vector<uint32_t> indices(k);
    std::vector<Scalar> dist2(k);
    k = index_.knnSearch(query.data(), k, indices.data(), dist2.data());
    std::vector<std::pair<uint32_t, Scalar>> out(k);
    for (size_t i = 0; i < k; ++i) out[i] = {indices[i], dist2[i]};
    return out;
  }

  // All points within `radius` (not squared), unsorted: {index, squared distance}. `out` is
  // reused to avoid allocations on hot paths.
  void Radius(const Point& query, Scalar radius,
              std::vector<std::pair<uint32_t, Scalar>>& out) const {
    out.clear();
    if (size() == 0) return;
    nanoflann::SearchParams params;
    params.sorted = false;
    index_.radiusSearch(query.data(), radius * radius, out, params);
  }

  size_t MemoryBytes() const {
    return points_.points.capacity() * sizeof(Point) +
           const_cast<Index&>(index_).usedMemory(const_cast<Index&>(index_));
  }

 private:
  struct Adaptor {
    std::vector<Point> points;
    size_t kdtree_get_point_count() const { return points.size(); }
    Scalar kdtree_get_pt(size_t i, size_t d) const { return points[i][d]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
      return false;
    }
  };
  using Index = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<Scalar, Adaptor>,
                                                    Adaptor, kDim, uint32_t>;
  Adaptor points_;
  Index index_;
};

}  // namespace forestmap::algorithms
