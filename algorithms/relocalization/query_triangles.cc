#include "algorithms/relocalization/query_triangles.h"

#include <algorithm>
#include <cmath>

namespace forestmap::algorithms {

double QuerySide(const std::vector<Eigen::Vector2d>& seed_xy, const MapIndexImpl& m) {
  constexpr size_t kSpacingTrees = 12;  // nearest query trees whose spacing is measured
  int lowest = -1, highest = -1;
  for (int level = 0; level < static_cast<int>(m.tables.size()); ++level) {
    if (!m.tables[level]) continue;
    if (lowest < 0) lowest = level;
    highest = level;
  }
  if (lowest < 0) return 0.0;
  const int own = m.levels.LevelFor(QuerySpacing(seed_xy, kSpacingTrees));
  return m.levels.Side(std::clamp(own - 1, lowest, highest));
}

std::vector<QueryTriangle> QueryTriangles(const std::vector<Eigen::Vector2d>& seed_xy,
                                          const MapIndexImpl& m, double max_side,
                                          double tolerance) {
  if (!(max_side > 0)) return {};
  TriangleOptions tri;
  tri.max_side = max_side + tolerance;
  tri.min_side = std::max(0.0, m.levels.min_side - tolerance);
  std::vector<std::vector<uint32_t>> neighbours(seed_xy.size());
  for (uint32_t i = 0; i < seed_xy.size(); ++i) {
    for (uint32_t j = 0; j < seed_xy.size(); ++j) {
      if (i != j && (seed_xy[i] - seed_xy[j]).norm() <= tri.max_side) neighbours[i].push_back(j);
    }
  }
  std::vector<Triangle> triangles = EnumerateTriangles(seed_xy, neighbours, tri);
  // Seeds are sorted by range, so the largest vertex index is the farthest vertex.
  auto farthest = [](const Triangle& t) {
    return std::max({t.vertex[0], t.vertex[1], t.vertex[2]});
  };
  std::stable_sort(triangles.begin(), triangles.end(),
                   [&](const Triangle& a, const Triangle& b) { return farthest(a) < farthest(b); });
  std::vector<QueryTriangle> out;
  const int bands = static_cast<int>(m.tables.size());
  for (const Triangle& t : triangles) {
    for (int band = 0; band < bands; ++band) {
      const double below = band > 0 ? m.levels.Side(band - 1) : 0.0;
      if (t.sides[2] + tolerance > below && t.sides[2] - tolerance <= m.levels.Side(band) &&
          m.tables[band]) {
        out.push_back({t, band});
      }
    }
  }
  return out;
}

void KeepSpread(std::vector<QueryTriangle>& triangles, size_t max, int per_seed) {
  if (triangles.size() <= max) return;
  std::vector<int> uses;
  std::vector<bool> keep(triangles.size(), false);
  size_t kept = 0;
  for (size_t t = 0; t < triangles.size() && kept < max; ++t) {
    const auto& v = triangles[t].triangle.vertex;
    const uint32_t highest = std::max({v[0], v[1], v[2]});
    if (uses.size() <= highest) uses.resize(highest + 1, 0);
    if (uses[v[0]] >= per_seed || uses[v[1]] >= per_seed || uses[v[2]] >= per_seed) continue;
    keep[t] = true;
    ++kept;
    for (uint32_t i : v) ++uses[i];
  }
  for (size_t t = 0; t < triangles.size() && kept < max; ++t) {
    if (!keep[t]) keep[t] = true, ++kept;
  }
  size_t out = 0;
  for (size_t t = 0; t < triangles.size(); ++t) {
    if (keep[t]) triangles[out++] = triangles[t];
  }
  triangles.resize(out);
}

}  // namespace forestmap::algorithms
