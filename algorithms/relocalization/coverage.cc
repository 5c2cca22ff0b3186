#include "algorithms/relocalization/coverage.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

#include "algorithms/core/delaunay.h"

namespace forestmap::algorithms {
namespace {

constexpr double kMaxCells = 134217728.0;  // 2^27 cells covered at most (64 MB of tiles)
// Row crossings of the rings at most: the fill sorts them (16 bytes each, 64 MB). A survey's
// boundary at 0.5 m crosses 2^22 rows with 2,000 km of north-south edges.
constexpr double kMaxCrossings = 4194304.0;  // 2^22

// The boundary of the kept triangles as rings, the kept region on the left of every edge:
// counter-clockwise outer rings, clockwise holes.
std::vector<std::vector<uint32_t>> TraceRings(const Triangulation& tri,
                                              const std::vector<bool>& kept) {
  auto boundary = [&](size_t t, int i) {
    const int32_t nb = tri.neighbours[t][i];
    return nb < 0 || !kept[nb];
  };
  std::vector<uint8_t> used(tri.triangles.size(), 0);  // bit i: edge i traced
  std::vector<std::vector<uint32_t>> rings;
  for (size_t start = 0; start < tri.triangles.size(); ++start) {
    if (!kept[start]) continue;
    for (int first = 0; first < 3; ++first) {
      if (!boundary(start, first) || (used[start] >> first & 1)) continue;
      std::vector<uint32_t> ring;
      size_t t = start;
      int i = first;
      while (!(used[t] >> i & 1)) {
        used[t] |= static_cast<uint8_t>(1 << i);
        ring.push_back(tri.triangles[t][(i + 1) % 3]);
        // The next boundary edge out of this edge's end b: around b through kept triangles.
        const uint32_t b = tri.triangles[t][(i + 2) % 3];
        while (true) {
          const auto& v = tri.triangles[t];
          const int k = v[0] == b ? 0 : v[1] == b ? 1 : 2;
          const int j = (k + 2) % 3;  // the edge from b to the next vertex counter-clockwise
          if (boundary(t, j)) {
            i = j;
            break;
          }
          t = static_cast<size_t>(tri.neighbours[t][j]);
        }
      }
      rings.push_back(std::move(ring));
    }
  }
  return rings;
}

std::vector<const Ring*> RingsOf(const Polygon& polygon) {
  std::vector<const Ring*> rings = {&polygon.outer};
  for (const Ring& hole : polygon.holes) rings.push_back(&hole);
  return rings;
}

struct Box {
  Eigen::Vector2d lo, hi;
  bool Holds(const Eigen::Vector2d& p) const {
    return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
  }
};

Box BoxOf(const Ring& ring) {
  Box box{ring[0], ring[0]};
  for (const Eigen::Vector2d& p : ring) box.lo = box.lo.cwiseMin(p), box.hi = box.hi.cwiseMax(p);
  return box;
}

}  // namespace

void CoverageOptions::Check() const {
  if (!(alpha_spacings > 0 && resolution > 0 && tree_margin >= 0)) {
    throw std::invalid_argument(
        "CoverageOptions: need alpha_spacings > 0, resolution > 0 m, tree_margin >= 0 m");
  }
}

std::vector<Polygon> AlphaShape(const std::vector<Eigen::Vector2d>& points,
                                const std::vector<double>& alpha) {
  if (alpha.size() != points.size()) {
    throw std::invalid_argument("AlphaShape: one alpha per point needed");
  }
  const Triangulation tri = Delaunay(points);
  std::vector<bool> kept(tri.triangles.size());
  for (size_t t = 0; t < tri.triangles.size(); ++t) {
    const auto& v = tri.triangles[t];
    const double radius = std::max({alpha[v[0]], alpha[v[1]], alpha[v[2]]});
    kept[t] = Circumradius(points[v[0]], points[v[1]], points[v[2]]) <= radius;
  }
  std::vector<Polygon> polygons;
  std::vector<Ring> holes;
  for (const std::vector<uint32_t>& indices : TraceRings(tri, kept)) {
    Ring ring;
    for (uint32_t i : indices) ring.push_back(points[i]);
    if (SignedArea(ring) > 0) {
      polygons.push_back({std::move(ring), {}});
    } else {
      holes.push_back(std::move(ring));
    }
  }
  // Each hole belongs to the smallest outer ring around it (an island in a clearing has its own).
  std::vector<Box> boxes;
  std::vector<double> areas;
  for (const Polygon& p : polygons) boxes.push_back(BoxOf(p.outer)), areas.push_back(Area(p));
  for (Ring& hole : holes) {
    // A point of the region just beside the hole: the middle of its first edge, moved a
    // thousandth of the edge's length to its left (the region's side).
    const Eigen::Vector2d a = hole[0], b = hole[1 % hole.size()];
    const Eigen::Vector2d probe =
        0.5 * (a + b) + 1e-3 * Eigen::Vector2d(a.y() - b.y(), b.x() - a.x());
    int owner = -1;
    for (size_t k = 0; k < polygons.size(); ++k) {
      if (!boxes[k].Holds(probe) || !Contains(polygons[k].outer, probe)) continue;
      if (owner < 0 || areas[k] < areas[owner]) owner = static_cast<int>(k);
    }
    if (owner >= 0) polygons[owner].holes.push_back(std::move(hole));
  }
  return polygons;
}

std::vector<Polygon> DeriveCoverage(const std::vector<Eigen::Vector2d>& points,
                                    const std::vector<float>& spacing,
                                    const CoverageOptions& options) {
  options.Check();
  std::vector<double> alpha(points.size());
  for (size_t i = 0; i < points.size(); ++i) alpha[i] = options.alpha_spacings * spacing.at(i);
  return AlphaShape(points, alpha);
}

// Paints cells into tiles while the grid is built.
class CoverageGrid::Painter {
 public:
  explicit Painter(double resolution) : resolution_(resolution) {}

  // Cells [i0, i1] of row j.
  void Span(int64_t j, int64_t i0, int64_t i1) {
    for (int64_t tx = i0 >> kTileBits; tx <= i1 >> kTileBits; ++tx) {
      const int64_t lo = std::max(i0, tx << kTileBits) & kTileMask;
      const int64_t hi = std::min(i1, (tx << kTileBits) + kTileMask) & kTileMask;
      const uint64_t bits =
          (hi == 63 ? ~uint64_t{0} : (uint64_t{1} << (hi + 1)) - 1) & ~((uint64_t{1} << lo) - 1);
      At(tx, j >> kTileBits).rows[j & kTileMask] |= bits;
    }
  }

  // Even-odd fill of the rings: a cell is painted when its centre is inside.
  void Fill(const std::vector<const Ring*>& rings) {
    std::vector<std::pair<int64_t, double>> crossings;  // (row, x)
    for (const Ring* ring : rings) {
      for (size_t a = 0, b = ring->size() - 1; a < ring->size(); b = a++) {
        const Eigen::Vector2d &p = (*ring)[a], &q = (*ring)[b];
        if (p.y() == q.y()) continue;
        const double y_lo = std::min(p.y(), q.y()), y_hi = std::max(p.y(), q.y());
        for (int64_t j = static_cast<int64_t>(std::ceil(y_lo / resolution_ - 0.5));; ++j) {
          const double yc = (j + 0.5) * resolution_;
          if (yc >= y_hi) break;
          if ((p.y() > yc) == (q.y() > yc)) continue;
          crossings.push_back({j, p.x() + (yc - p.y()) * (q.x() - p.x()) / (q.y() - p.y())});
        }
      }
    }
    std::sort(crossings.begin(), crossings.end());
    for (size_t k = 0; k + 1 < crossings.size(); k += 2) {
      const int64_t j = crossings[k].first;
      if (crossings[k + 1].first != j) {  // an odd row cannot happen with closed rings
        --k;
        continue;
      }
      const int64_t i0 = static_cast<int64_t>(std::ceil(crossings[k].second / resolution_ - 0.5));
      const int64_t i1 =
          static_cast<int64_t>(std::ceil(crossings[k + 1].second / resolution_ - 0.5)) - 1;
      if (i0 <= i1) Span(j, i0, i1);
    }
  }

  // The cells whose centre lies within `radius` of p.
  void Disc(const Eigen::Vector2d& p, double radius) {
    const int64_t j0 = static_cast<int64_t>(std::ceil((p.y() - radius) / resolution_ - 0.5));
    for (int64_t j = j0;; ++j) {
      const double dy = (j + 0.5) * resolution_ - p.y();
      if (dy > radius) break;
      const double dx = std::sqrt(std::max(0.0, radius * radius - dy * dy));
      const int64_t i0 = static_cast<int64_t>(std::ceil((p.x() - dx) / resolution_ - 0.5));
      const int64_t i1 = static_cast<int64_t>(std::floor((p.x() + dx) / resolution_ - 0.5));
      if (i0 <= i1) Span(j, i0, i1);
    }
  }

  std::unordered_map<uint64_t, Tile>& tiles() { return tiles_; }

 private:
  Tile& At(int64_t tx, int64_t ty) { return tiles_[TileDirectory::Key(tx, ty)]; }

  double resolution_;
  std::unordered_map<uint64_t, Tile> tiles_;
};

CoverageGrid::CoverageGrid(const std::vector<Polygon>& polygons,
                           const std::vector<Eigen::Vector2d>& points, double margin,
                           double resolution) {
  CheckPolygons(polygons);
  if (!(resolution > 0 && margin >= 0)) {
    throw std::invalid_argument("CoverageGrid: need resolution > 0 and margin >= 0");
  }
  // Coarser cells where the polygons would hold more than kMaxCells cells or kMaxCrossings row
  // crossings.
  double outer_area = 0, rows = 0;
  for (const Polygon& p : polygons) {
    outer_area += std::abs(SignedArea(p.outer));
    for (const Ring* ring : RingsOf(p)) {
      for (size_t a = 0, b = ring->size() - 1; a < ring->size(); b = a++) {
        rows += std::abs((*ring)[a].y() - (*ring)[b].y());
      }
    }
  }
  resolution = std::max({resolution, std::sqrt(outer_area / kMaxCells), rows / kMaxCrossings});
  inverse_resolution_ = 1.0 / resolution;
  Painter painter(resolution);
  for (const Polygon& p : polygons) painter.Fill(RingsOf(p));
  const double reach = margin + resolution * M_SQRT1_2;  // every point within margin: covered
  for (const Eigen::Vector2d& p : points) painter.Disc(p, reach);

  // Wholly covered tiles share one stored tile, those with wholly covered neighbours another.
  std::vector<std::pair<uint64_t, int32_t>> entries;
  tiles_.resize(2);
  for (Tile& full : tiles_) std::fill(std::begin(full.rows), std::end(full.rows), ~uint64_t{0});
  size_t cells = 0;
  for (auto& [key, tile] : painter.tiles()) {
    bool full = true;
    for (uint64_t row : tile.rows) cells += std::popcount(row), full = full && row == ~uint64_t{0};
    if (full) {
      entries.push_back({key, kFullTile});
    } else {
      entries.push_back({key, static_cast<int32_t>(tiles_.size())});
      tiles_.push_back(tile);
    }
  }
  std::sort(entries.begin(), entries.end());
  directory_.Index(entries);
  std::vector<std::pair<uint64_t, int32_t>> deep = entries;
  for (auto& [key, index] : deep) {
    const int64_t tx = static_cast<int32_t>(key >> 32), ty = static_cast<int32_t>(key & 0xFFFFFFFF);
    bool surrounded = index == kFullTile;
    for (int dx = -1; dx <= 1 && surrounded; ++dx) {
      for (int dy = -1; dy <= 1 && surrounded; ++dy) {
        surrounded = directory_.Find(TileDirectory::Key(tx + dx, ty + dy)) == kFullTile;
      }
    }
    if (surrounded) index = kDeepTile;
  }
  directory_.Index(deep);
  area_ = static_cast<double>(cells) * resolution * resolution;
  // Cell edges between a covered and an uncovered cell: within each tile, and across its left
  // and lower borders (its right and upper ones too where no tile lies beyond).
  size_t edges = 0;
  auto row_of = [&](int64_t tx, int64_t ty, int r) {
    const int32_t t = directory_.Find(TileDirectory::Key(tx, ty));
    return t < 0 ? uint64_t{0} : tiles_[t].rows[r];
  };
  for (const auto& [key, index] : entries) {
    const Tile& tile = tiles_[index];
    const int64_t tx = static_cast<int32_t>(key >> 32), ty = static_cast<int32_t>(key & 0xFFFFFFFF);
    for (int r = 0; r < 64; ++r) {
      const uint64_t row = tile.rows[r];
      edges += std::popcount((row ^ (row >> 1)) & (~uint64_t{0} >> 1));
      edges += std::popcount(row ^ (r < 63 ? tile.rows[r + 1] : row_of(tx, ty + 1, 0)));
      edges += (row & 1) != (row_of(tx - 1, ty, r) >> 63);
      if (directory_.Find(TileDirectory::Key(tx + 1, ty)) < 0) edges += row >> 63;
    }
    if (directory_.Find(TileDirectory::Key(tx, ty - 1)) < 0) edges += std::popcount(tile.rows[0]);
  }
  perimeter_ = static_cast<double>(edges) * resolution;
}

double CoverageGrid::CoveredShare(double x0, double y0, double side) const {
  constexpr int kSamples = 16;
  int covered = 0;
  for (int a = 0; a < kSamples; ++a) {
    for (int b = 0; b < kSamples; ++b) {
      covered += Covered(x0 + (a + 0.5) * side / kSamples, y0 + (b + 0.5) * side / kSamples);
    }
  }
  return covered / static_cast<double>(kSamples * kSamples);
}

}  // namespace forestmap::algorithms
