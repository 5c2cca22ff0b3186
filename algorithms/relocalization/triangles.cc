#include "algorithms/relocalization/triangles.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace forestmap::algorithms {

void TriangleOptions::Check() const {
  if (!(min_side >= 0 && max_side > min_side)) {
    throw std::invalid_argument("TriangleOptions: need 0 <= min_side < max_side");
  }
}

Triangle MakeTriangle(const std::vector<Eigen::Vector2d>& points, uint32_t i, uint32_t j,
                      uint32_t k) {
  // Side opposite each vertex.
  std::array<std::pair<float, uint32_t>, 3> opposite = {{
      {static_cast<float>((points[j] - points[k]).norm()), i},
      {static_cast<float>((points[k] - points[i]).norm()), j},
      {static_cast<float>((points[i] - points[j]).norm()), k},
  }};
  std::sort(opposite.begin(), opposite.end());
  Triangle t;
  for (int v = 0; v < 3; ++v) {
    t.sides[v] = opposite[v].first;
    t.vertex[v] = opposite[v].second;
  }
  return t;
}

std::vector<Triangle> EnumerateTriangles(const std::vector<Eigen::Vector2d>& points,
                                         const std::vector<std::vector<uint32_t>>& neighbours,
                                         const TriangleOptions& options, size_t begin, size_t end) {
  options.Check();
  const double max2 = options.max_side * options.max_side;
  const double min2 = options.min_side * options.min_side;
  std::vector<Triangle> out;
  for (size_t i = begin; i < std::min(end, points.size()); ++i) {
    // Each triangle once: from its smallest vertex index.
    std::vector<uint32_t> higher;
    for (uint32_t j : neighbours[i]) {
      const double d2 = (points[j] - points[i]).squaredNorm();
      if (j > i && d2 >= min2 && d2 <= max2) higher.push_back(j);
    }
    for (size_t a = 0; a < higher.size(); ++a) {
      for (size_t b = a + 1; b < higher.size(); ++b) {
        const double d2 = (points[higher[a]] - points[higher[b]]).squaredNorm();
        if (d2 < min2 || d2 > max2) continue;
        out.push_back(MakeTriangle(points, static_cast<uint32_t>(i), higher[a], higher[b]));
      }
    }
  }
  return out;
}

}  // namespace forestmap::algorithms
