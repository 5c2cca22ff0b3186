#include "algorithms/relocalization/triangle_table.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace forestmap::algorithms {

HeadingTable::HeadingTable() {
  for (int i = 0; i < 1024; ++i) {
    const double a = 2 * M_PI * i / 1024.0;
    cos_sin[i][0] = static_cast<float>(std::cos(a));
    cos_sin[i][1] = static_cast<float>(std::sin(a));
  }
}

const HeadingTable& Headings() {
  static const HeadingTable table;
  return table;
}

TriangleFrame FrameOf(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                      const Eigen::Vector2d& c) {
  const Eigen::Vector2d centroid = (a + b + c) / 3.0;
  const Eigen::Vector2d ab = b - a, ac = c - a;
  const double cross = ab.x() * ac.y() - ab.y() * ac.x();
  // Nearly collinear triangles (height under 5% of the long side) have no reliable orientation.
  const int turn = std::abs(cross) < 0.05 * ab.squaredNorm() ? 0 : (cross > 0 ? 1 : -1);
  const double length = ab.norm();
  TriangleFrame frame;
  frame.cx = static_cast<float>(centroid.x());
  frame.cy = static_cast<float>(centroid.y());
  frame.cos_heading = length > 0 ? static_cast<float>(ab.x() / length) : 1.f;
  frame.sin_heading = length > 0 ? static_cast<float>(ab.y() / length) : 0.f;
  frame.turn = turn;
  return frame;
}

TriangleTable::TriangleTable(std::span<const Triangle> triangles,
                             const std::vector<Eigen::Vector2d>& points, double max_side) {
  if (!(max_side > 0 && max_side <= kMaxTableSide)) {
    throw std::invalid_argument("TriangleTable: max_side must be in (0, 32] m");
  }
  // About one triangle a cell (sorted keys fill a sixth of the cube), at most 64^3 cells.
  cells_ = std::clamp(static_cast<int>(std::cbrt(6.0 * triangles.size())), 8, 64);
  inverse_cell_ = static_cast<float>((cells_ - 1) / max_side);
  const size_t cells = static_cast<size_t>(cells_) * cells_ * cells_;
  auto cell_of = [&](const Triangle& t) {
    return Index(std::min(Cell(t.sides[0]), cells_ - 1), std::min(Cell(t.sides[1]), cells_ - 1),
                 std::min(Cell(t.sides[2]), cells_ - 1));
  };
  // Counting sort by key cell.
  start_.assign(cells + 1, 0);
  for (const Triangle& t : triangles) ++start_[cell_of(t) + 1];
  for (size_t i = 0; i < cells; ++i) start_[i + 1] += start_[i];
  std::vector<uint32_t> next(start_.begin(), start_.end() - 1);
  triangles_.resize(triangles.size());
  for (const Triangle& t : triangles) {
    IndexedTriangle& out = triangles_[next[cell_of(t)]++];
    const TriangleFrame frame =
        FrameOf(points[t.vertex[0]], points[t.vertex[1]], points[t.vertex[2]]);
    out.cx = frame.cx;
    out.cy = frame.cy;
    const double turns = std::atan2(frame.sin_heading, frame.cos_heading) / (2 * M_PI);
    out.heading =
        static_cast<uint16_t>(std::lround((turns < 0 ? turns + 1 : turns) * 65536) & 0xFFFF);
    for (int d = 0; d < 3; ++d) {
      const double side = std::min<double>(t.sides[d], kMaxTableSide);
      out.side_key[d] = static_cast<uint16_t>(std::lround(side * 1000.0));
    }
    if (frame.turn != 0) out.side_key[0] |= 0x8000;
    if (frame.turn > 0) out.side_key[1] |= 0x8000;
  }
}

}  // namespace forestmap::algorithms
