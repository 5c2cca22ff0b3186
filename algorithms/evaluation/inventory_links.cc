#include "algorithms/evaluation/inventory_links.h"

#include <algorithm>
#include <array>
#include <utility>

#include "algorithms/core/kdtree.h"

namespace forestmap::algorithms {
namespace {

// m: nanoflann's radius search keeps points strictly inside the radius, in coordinates shifted
// to a local origin: the search radius is widened by this much (far above the rounding of
// projected coordinates, ~1e-9 m), and every candidate is then checked with LinkGap on the
// original coordinates, so that the pairs are exactly those a brute force finds.
constexpr double kSearchSlack = 1e-6;

}  // namespace

bool LinkBefore(const InventoryLink& a, const InventoryLink& b) {
  if (a.distance != b.distance) return a.distance < b.distance;
  if (a.detected != b.detected) return a.detected < b.detected;
  return a.reference < b.reference;
}

double LinkGap(const DetectedTree& detected, const MapTree& reference) {
  return (detected.position.head<2>() - reference.position.head<2>()).norm();
}

std::vector<InventoryLink> LinkOneToOne(const std::vector<DetectedTree>& detected,
                                        const std::vector<MapTree>& reference, double distance) {
  if (detected.empty() || reference.empty()) return {};
  // Coordinates relative to the reference's first tree: projected coordinates are large numbers,
  // and the search radius is small beside them.
  const Eigen::Vector2d origin = reference.front().position.head<2>();
  std::vector<std::array<double, 2>> points;
  points.reserve(reference.size());
  for (const MapTree& tree : reference) {
    const Eigen::Vector2d p = tree.position.head<2>() - origin;
    points.push_back({p.x(), p.y()});
  }
  const KdTree<double, 2> index(std::move(points));
  const double radius = distance + kSearchSlack;
  std::vector<InventoryLink> candidates;
  std::vector<std::pair<uint32_t, double>> near;
  for (size_t d = 0; d < detected.size(); ++d) {
    const Eigen::Vector2d p = detected[d].position.head<2>() - origin;
    if (!p.allFinite()) continue;
    index.Radius({p.x(), p.y()}, radius, near);
    for (const auto& [r, squared] : near) {
      const double gap = LinkGap(detected[d], reference[r]);
      if (gap <= distance) {
        candidates.push_back({static_cast<int>(d), static_cast<int>(r), gap});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end(), LinkBefore);
  std::vector<bool> detected_used(detected.size()), reference_used(reference.size());
  std::vector<InventoryLink> links;
  for (const InventoryLink& link : candidates) {
    if (detected_used[link.detected] || reference_used[link.reference]) continue;
    detected_used[link.detected] = reference_used[link.reference] = true;
    links.push_back(link);
  }
  return links;
}

}  // namespace forestmap::algorithms
