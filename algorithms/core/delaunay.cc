#include "algorithms/core/delaunay.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace forestmap::algorithms {
namespace {

using Int128 = __int128;

struct Point {
  int64_t x = 0, y = 0;
};

// Rounded coordinates span at most 2^26 quanta, the super triangle 9 times that: every
// difference fits 31 bits, every 2 x 2 determinant 63 bits and the in-circle sum 126 bits.
constexpr double kMaxQuanta = 67108864.0;  // 2^26
constexpr double kQuantum = 0.001;         // m, at least

// > 0 when c lies left of a -> b (a, b, c counter-clockwise), 0 when collinear.
int64_t Orient(const Point& a, const Point& b, const Point& c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

// Whether d lies strictly inside the circle through the counter-clockwise a, b, c.
bool InCircle(const Point& a, const Point& b, const Point& c, const Point& d) {
  const int64_t adx = a.x - d.x, ady = a.y - d.y, bdx = b.x - d.x, bdy = b.y - d.y;
  const int64_t cdx = c.x - d.x, cdy = c.y - d.y;
  const Int128 alift = Int128(adx * adx + ady * ady), blift = Int128(bdx * bdx + bdy * bdy);
  const Int128 clift = Int128(cdx * cdx + cdy * cdy);
  return alift * Int128(bdx * cdy - cdx * bdy) + blift * Int128(cdx * ady - adx * cdy) +
             clift * Int128(adx * bdy - bdx * ady) >
         0;
}

// Position along a Hilbert curve of order 16 (Skilling's form): consecutive insertions land
// near each other, so each walk is short.
uint64_t HilbertKey(uint32_t x, uint32_t y) {
  uint64_t key = 0;
  for (uint32_t s = 1u << 15; s > 0; s >>= 1) {
    const uint32_t rx = (x & s) ? 1 : 0, ry = (y & s) ? 1 : 0;
    key += static_cast<uint64_t>(s) * s * ((3 * rx) ^ ry);
    if (ry == 0) {
      if (rx == 1) {
        x = s - 1 - x;
        y = s - 1 - y;
      }
      std::swap(x, y);
    }
  }
  return key;
}

struct Tri {
  std::array<uint32_t, 3> v;
  std::array<int32_t, 3> n;
};

class Builder {
 public:
  explicit Builder(std::vector<Point> points) : p_(std::move(points)) {}

  void Insert(uint32_t id) {
    const int32_t start = Locate(p_[id]);
    ++stamp_;
    cavity_.assign(1, start);
    seen_[start] = stamp_;
    boundary_.clear();
    for (size_t k = 0; k < cavity_.size(); ++k) {
      const int32_t t = cavity_[k];
      for (int i = 0; i < 3; ++i) {
        const int32_t nb = tris_[t].n[i];
        if (nb >= 0 && seen_[nb] == stamp_) continue;  // in the cavity (or tested outside)
        if (nb >= 0 && Inside(nb, p_[id])) {
          seen_[nb] = stamp_;
          cavity_.push_back(nb);
          continue;
        }
        boundary_.push_back({tris_[t].v[(i + 1) % 3], tris_[t].v[(i + 2) % 3], nb});
      }
    }
    Fan(id);
  }

  int32_t AddTriangle(const Tri& tri) {
    tris_.push_back(tri);
    seen_.push_back(0);
    return static_cast<int32_t>(tris_.size() - 1);
  }

  const std::vector<Tri>& triangles() const { return tris_; }
  const std::vector<int32_t>& dead() const { return free_; }

 private:
  struct Edge {
    uint32_t a, b;
    int32_t outside;  // the triangle beyond the edge (-1: none)
  };

  bool Inside(int32_t t, const Point& d) const {
    const Tri& tri = tris_[t];
    return InCircle(p_[tri.v[0]], p_[tri.v[1]], p_[tri.v[2]], d);
  }

  // The triangle containing p (on its boundary included): a visibility walk from the last
  // triangle made, a scan of every triangle if it ever runs too long.
  int32_t Locate(const Point& q) const {
    int32_t t = last_;
    const size_t max_steps = 4 * tris_.size() + 16;
    for (size_t step = 0; step < max_steps; ++step) {
      const Tri& tri = tris_[t];
      int next = -1;
      for (int k = 0; k < 3 && next < 0; ++k) {
        const int i = (k + static_cast<int>(step)) % 3;
        if (Orient(p_[tri.v[(i + 1) % 3]], p_[tri.v[(i + 2) % 3]], q) < 0) next = i;
      }
      if (next < 0) return t;
      t = tri.n[next];
    }
    for (size_t s = 0; s < tris_.size(); ++s) {
      const Tri& tri = tris_[s];
      if (seen_[s] < 0) continue;  // freed slot
      if (Orient(p_[tri.v[0]], p_[tri.v[1]], q) >= 0 &&
          Orient(p_[tri.v[1]], p_[tri.v[2]], q) >= 0 &&
          Orient(p_[tri.v[2]], p_[tri.v[0]], q) >= 0) {
        return static_cast<int32_t>(s);
      }
    }
    throw std::logic_error("Delaunay: point outside the super triangle");
  }

  // Replaces the cavity with the triangles joining its boundary edges to `id`.
  void Fan(uint32_t id) {
    std::vector<int32_t>& slots = cavity_;  // reused, then new slots
    made_.clear();
    for (size_t k = 0; k < boundary_.size(); ++k) {
      const Edge& e = boundary_[k];
      const Tri tri{{e.a, e.b, id}, {-1, -1, e.outside}};
      int32_t t;
      if (k < slots.size()) {
        t = slots[k];
        tris_[t] = tri;
      } else if (!free_.empty()) {
        t = free_.back();
        free_.pop_back();
        tris_[t] = tri;
        seen_[t] = 0;
      } else {
        t = AddTriangle(tri);
      }
      if (e.outside >= 0) {  // its edge (b, a) is the one opposite its vertex off the edge
        Tri& out = tris_[e.outside];
        for (int i = 0; i < 3; ++i) {
          if (out.v[i] != e.a && out.v[i] != e.b) out.n[i] = t;
        }
      }
      made_.push_back(t);
    }
    for (size_t k = boundary_.size(); k < slots.size(); ++k) {
      seen_[slots[k]] = -1;  // freed
      free_.push_back(slots[k]);
    }
    // Neighbours among the new triangles: (a, b, id) meets (b, c, id) across b -> id and
    // (x, a, id) across id -> a.
    for (int32_t t : made_) {
      for (int32_t u : made_) {
        if (tris_[u].v[0] == tris_[t].v[1]) tris_[t].n[0] = u;
        if (tris_[u].v[1] == tris_[t].v[0]) tris_[t].n[1] = u;
      }
    }
    last_ = made_.front();
  }

  std::vector<Point> p_;
  std::vector<Tri> tris_;
  std::vector<int64_t> seen_;  // per triangle: the insertion that last tested it; -1 freed
  std::vector<int32_t> free_, cavity_, made_;
  std::vector<Edge> boundary_;
  int64_t stamp_ = 0;
  int32_t last_ = 0;
};

}  // namespace

double Circumradius(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const double ab = (b - a).norm(), bc = (c - b).norm(), ca = (a - c).norm();
  const double twice_area = std::abs((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
  return twice_area > 0 ? ab * bc * ca / (2 * twice_area) : std::numeric_limits<double>::infinity();
}

Triangulation Delaunay(const std::vector<Eigen::Vector2d>& points) {
  Triangulation out;
  if (points.size() < 3) return out;
  Eigen::Vector2d lo = points[0], hi = points[0];
  for (const Eigen::Vector2d& p : points) {
    if (!p.allFinite()) throw std::invalid_argument("Delaunay: a point is not finite");
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double quantum = std::max(kQuantum, (hi - lo).maxCoeff() / kMaxQuanta);
  const uint32_t n = static_cast<uint32_t>(points.size());
  std::vector<Point> q(n + 3);
  for (uint32_t i = 0; i < n; ++i) {
    q[i] = {std::llround((points[i].x() - lo.x()) / quantum),
            std::llround((points[i].y() - lo.y()) / quantum)};
  }
  const int64_t extent = std::max<int64_t>(16, std::llround((hi - lo).maxCoeff() / quantum));
  const int64_t k = 4 * extent;  // a super triangle holding the box [0, extent]^2 well inside
  q[n] = {-k, -k};
  q[n + 1] = {2 * k + extent, -k};
  q[n + 2] = {-k, 2 * k + extent};
  // Insertion order: along the Hilbert curve, the first of each rounded position only.
  std::vector<std::pair<uint64_t, uint32_t>> order(n);
  const double to_curve = 65535.0 / static_cast<double>(extent);
  for (uint32_t i = 0; i < n; ++i) {
    order[i] = {HilbertKey(static_cast<uint32_t>(q[i].x * to_curve),
                           static_cast<uint32_t>(q[i].y * to_curve)),
                i};
  }
  std::vector<uint32_t> by_position(n);
  std::iota(by_position.begin(), by_position.end(), 0u);
  std::sort(by_position.begin(), by_position.end(), [&](uint32_t a, uint32_t b) {
    return q[a].x != q[b].x ? q[a].x < q[b].x : q[a].y != q[b].y ? q[a].y < q[b].y : a < b;
  });
  std::vector<bool> duplicate(n, false);
  for (uint32_t i = 1; i < n; ++i) {
    const Point &a = q[by_position[i - 1]], &b = q[by_position[i]];
    duplicate[by_position[i]] = a.x == b.x && a.y == b.y;
  }
  std::sort(order.begin(), order.end());

  Builder builder(q);
  builder.AddTriangle({{n, n + 1, n + 2}, {-1, -1, -1}});
  for (const auto& [key, i] : order) {
    if (!duplicate[i]) builder.Insert(i);
  }
  // The triangles without a super vertex, renumbered.
  const std::vector<Tri>& tris = builder.triangles();
  std::vector<int32_t> renumber(tris.size(), -1);
  std::vector<bool> freed(tris.size(), false);
  for (int32_t t : builder.dead()) freed[t] = true;
  for (size_t t = 0; t < tris.size(); ++t) {
    const auto& v = tris[t].v;
    if (freed[t] || v[0] >= n || v[1] >= n || v[2] >= n) continue;
    renumber[t] = static_cast<int32_t>(out.triangles.size());
    out.triangles.push_back(v);
  }
  out.neighbours.resize(out.triangles.size());
  for (size_t t = 0; t < tris.size(); ++t) {
    if (renumber[t] < 0) continue;
    for (int i = 0; i < 3; ++i) {
      const int32_t nb = tris[t].n[i];
      out.neighbours[renumber[t]][i] = nb >= 0 ? renumber[nb] : -1;
    }
  }
  return out;
}

}  // namespace forestmap::algorithms
