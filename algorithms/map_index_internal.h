#pragma once
// Internal layout of MapIndex, shared by the index builder and the relocalizer only.

#include <array>
#include <memory>
#include <vector>

#include "algorithms/kdtree.h"
#include "algorithms/map_index.h"
#include "algorithms/triangles.h"

namespace forestmap::algorithms {

// Where a triangle sits (kd coordinates): enough to turn a key match into a sensor pose
// without touching the vertices again.
// 12 bytes: the orientation is packed into the heading (heading + 8 * turn).
struct TriangleFrame {
  float cx = 0, cy = 0;  // m, centroid
  float packed = 0;

  // rad, direction of the longest side, from vertex A to vertex B.
  float heading() const { return packed > 4.f ? packed - 8.f : packed < -4.f ? packed + 8.f : packed; }
  // Orientation of A, B, C: +1 counter-clockwise, -1 clockwise, 0 nearly collinear.
  int turn() const { return packed > 4.f ? 1 : packed < -4.f ? -1 : 0; }
};

TriangleFrame FrameOf(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c);

class MapIndexImpl {
 public:
  std::vector<MapTree> trees;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // map frame; kd coordinates are relative
  std::unique_ptr<KdTree<float, 2>> positions;       // tree i at positions->point(i) + origin
  std::vector<TriangleFrame> triangle_frames;          // pose of each indexed triangle
  std::unique_ptr<KdTree<float, 3>> triangle_keys;          // sorted side lengths
  TriangleOptions triangle_options;
  bool has_z = false;
  bool has_dbh = false;

  Eigen::Vector2d Xy(uint32_t i) const {
    const auto& p = positions->point(i);
    return Eigen::Vector2d(p[0], p[1]);
  }
};

}  // namespace forestmap::algorithms
