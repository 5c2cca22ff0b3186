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

void KeepSpread(std::vector<QueryTriangle>& triangles, size_t max, int first_per_seed,
                int per_seed) {
  std::vector<int> uses;
  std::vector<bool> taken(triangles.size(), false);
  std::vector<QueryTriangle> out;
  out.reserve(std::min(max, triangles.size()));
  per_seed = std::max(1, per_seed);
  for (int cap = std::clamp(first_per_seed, 1, per_seed);; cap = std::min(2 * cap, per_seed)) {
    for (size_t t = 0; t < triangles.size() && out.size() < max; ++t) {
      const auto& v = triangles[t].triangle.vertex;
      const uint32_t highest = std::max({v[0], v[1], v[2]});
      if (uses.size() <= highest) uses.resize(highest + 1, 0);
      if (taken[t] || uses[v[0]] >= cap || uses[v[1]] >= cap || uses[v[2]] >= cap) continue;
      taken[t] = true;
      out.push_back(triangles[t]);
      for (uint32_t i : v) ++uses[i];
    }
    if (cap >= per_seed) break;
  }
  for (size_t t = 0; t < triangles.size() && out.size() < max; ++t) {
    if (!taken[t]) out.push_back(triangles[t]);
  }
  triangles = std::move(out);
}

}  // namespace forestmap::algorithms
