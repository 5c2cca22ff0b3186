#include "algorithms/detection/scan_filter.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {

void ScanFilterOptions::Check() const {
  if (!(self_radius >= 0))
    throw std::invalid_argument("ScanFilterOptions: self_radius must be >= 0");
  if (!(max_range >= 0)) throw std::invalid_argument("ScanFilterOptions: max_range must be >= 0");
}

ScanFilterResult FilterScan(const PointCloud& cloud, const ScanFilterOptions& options) {
  options.Check();
  ScanFilterResult result;
  result.points.reserve(cloud.size());
  result.source_index.reserve(cloud.size());
  const float self2 = static_cast<float>(options.self_radius * options.self_radius);
  const float range2 = static_cast<float>(options.max_range * options.max_range);
  constexpr float kOrigin2 = 1e-6f;  // (1 mm)^2
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z())) {
      ++result.invalid;
      continue;
    }
    const float d2 = p.squaredNorm();
    if (d2 <= kOrigin2) {
      ++result.origin_duplicates;
      continue;
    }
    if (d2 <= self2) {
      ++result.self_returns;
      continue;
    }
    if (range2 > 0 && p.x() * p.x() + p.y() * p.y() > range2) {
      ++result.out_of_range;
      continue;
    }
    result.points.push_back(p);
    result.source_index.push_back(static_cast<uint32_t>(i));
  }
  return result;
}

}  // namespace forestmap::algorithms
