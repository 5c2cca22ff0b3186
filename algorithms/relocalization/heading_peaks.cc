#include "algorithms/relocalization/heading_peaks.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

std::vector<double> HeadingPeaks(const MapIndexImpl& m, const LevelledQuery& q,
                                 const Eigen::Vector2d& at, int count) {
  constexpr int kBins = 72;                // 5 deg
  constexpr double kMinRange = 2.0;        // m, nearer bearings swing with a small position error
  constexpr double kRangeTolerance = 1.0;  // m
  double max_range = 0;
  std::vector<std::pair<double, double>> query;  // range, bearing
  for (const Eigen::Vector2d& p : q.xy) {
    if (p.norm() < kMinRange) continue;
    query.push_back({p.norm(), std::atan2(p.y(), p.x())});
    max_range = std::max(max_range, p.norm());
  }
  std::vector<double> votes(kBins, 0.0);
  std::vector<std::pair<uint32_t, float>> found;
  m.positions->Radius({static_cast<float>(at.x()), static_cast<float>(at.y())},
                      static_cast<float>(max_range + kRangeTolerance), found);
  for (const auto& [j, d2] : found) {
    const Eigen::Vector2d d = m.Xy(j) - at;
    const double range = std::sqrt(d2);
    if (range < kMinRange) continue;
    const double bearing = std::atan2(d.y(), d.x());
    for (const auto& [query_range, query_bearing] : query) {
      if (std::abs(query_range - range) > kRangeTolerance) continue;
      const double yaw = WrapAngle(bearing - query_bearing);
      votes[static_cast<int>((yaw + M_PI) / (2 * M_PI) * kBins) % kBins] += 1.0;
    }
  }
  std::vector<double> peaks;
  for (int n = 0; n < count; ++n) {
    const int best = static_cast<int>(std::max_element(votes.begin(), votes.end()) - votes.begin());
    if (votes[best] <= 0) break;
    peaks.push_back(-M_PI + (best + 0.5) * 2 * M_PI / kBins);
    for (int k = -2; k <= 2; ++k) votes[(best + k + kBins) % kBins] = 0;  // separate the peaks
  }
  return peaks;
}

}  // namespace forestmap::algorithms
