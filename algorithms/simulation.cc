#include "algorithms/simulation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace forestmap::algorithms {
namespace {

using Rng = std::mt19937_64;

constexpr double kUnknownDbhRadius = 0.15;    // m, trunk radius assumed for occlusion
constexpr double kFalseStemClearance = 1.0;   // m, false stems keep this far from map trees
constexpr int kMaxPlacementTries = 100;       // per tree / false stem before giving up
constexpr double kMaxHardCoreCoverage = 0.4;  // RSA jams at ~0.547; stay clear of it
constexpr double kMaxGeneratedTrees = 1e8;    // guards against a typo allocating terabytes
constexpr double kMaxTilt = 1.5;              // rad
constexpr double kMinDetectedDbh = 0.01;      // m
constexpr int kMaxFocalTrees = 20000;         // trees used for the statistics of large maps
constexpr double kMinClusterExcess = 0.5;     // extra neighbours per tree deemed clustering

[[noreturn]] void Invalid(const std::string& what, double value) {
  std::ostringstream message;
  message << what << " (got " << value << ")";
  throw std::invalid_argument(message.str());
}

void Require(bool ok, const std::string& what, double value) {
  if (!ok) Invalid(what, value);
}

double Gaussian(Rng& rng, double sd) {
  return sd > 0 ? std::normal_distribution<double>(0.0, sd)(rng) : 0.0;
}

double Uniform(Rng& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// `value` wrapped into [0, size): cluster offsets wrap around the area so that the intensity
// stays uniform (a torus).
double WrapInto(double value, double size) {
  return std::clamp(value - size * std::floor(value / size), 0.0, std::nextafter(size, 0.0));
}

// Sorted disjoint angular intervals within [-pi, pi]: the shadows cast by trunks.
class ShadowSet {
 public:
  void Add(double lo, double hi) {
    if (hi - lo >= 2 * M_PI) return AddRaw(-M_PI, M_PI);
    if (lo < -M_PI) {
      AddRaw(lo + 2 * M_PI, M_PI);
      lo = -M_PI;
    }
    if (hi > M_PI) {
      AddRaw(-M_PI, hi - 2 * M_PI);
      hi = M_PI;
    }
    AddRaw(lo, hi);
  }
  bool Covers(double angle) const {
    auto it = intervals_.upper_bound(angle);
    if (it == intervals_.begin()) return false;
    return angle <= std::prev(it)->second;
  }

 private:
  void AddRaw(double lo, double hi) {
    auto it = intervals_.upper_bound(lo);
    if (it != intervals_.begin() && std::prev(it)->second >= lo) {
      lo = std::prev(it)->first;
      hi = std::max(hi, std::prev(it)->second);
      it = intervals_.erase(std::prev(it));
    }
    while (it != intervals_.end() && it->first <= hi) {
      hi = std::max(hi, it->second);
      it = intervals_.erase(it);
    }
    intervals_[lo] = hi;
  }
  std::map<double, double> intervals_;  // rad, start -> end
};

// Incremental grid for the hard-core test during generation: cells no smaller than the spacing,
// so only the 3x3 neighbourhood needs checking; per-cell linked lists.
class HardCoreGrid {
 public:
  HardCoreGrid(double width, double height, double spacing, double density)
      : spacing_(spacing), cell_(std::max(spacing, 1.0 / std::sqrt(density))) {
    nx_ = static_cast<int>(std::ceil(width / cell_)) + 1;
    ny_ = static_cast<int>(std::ceil(height / cell_)) + 1;
    if (spacing_ > 0) head_.assign(static_cast<size_t>(nx_) * ny_, -1);
  }
  bool TryInsert(const Eigen::Vector2d& p) {
    if (spacing_ <= 0) return Insert(p, 0);
    const int cx = std::clamp(static_cast<int>(p.x() / cell_), 0, nx_ - 1);
    const int cy = std::clamp(static_cast<int>(p.y() / cell_), 0, ny_ - 1);
    for (int y = std::max(cy - 1, 0); y <= std::min(cy + 1, ny_ - 1); ++y) {
      for (int x = std::max(cx - 1, 0); x <= std::min(cx + 1, nx_ - 1); ++x) {
        for (int i = head_[Cell(x, y)]; i >= 0; i = next_[i]) {
          if ((points_[i] - p).squaredNorm() < spacing_ * spacing_) return false;
        }
      }
    }
    return Insert(p, Cell(cx, cy));
  }
  const std::vector<Eigen::Vector2d>& points() const { return points_; }

 private:
  size_t Cell(int x, int y) const { return static_cast<size_t>(y) * nx_ + x; }
  bool Insert(const Eigen::Vector2d& p, size_t cell) {
    if (spacing_ > 0) {
      next_.push_back(head_[cell]);
      head_[cell] = static_cast<int>(points_.size());
    }
    points_.push_back(p);
    return true;
  }
  double spacing_, cell_;
  int nx_ = 0, ny_ = 0;
  std::vector<int> head_, next_;
  std::vector<Eigen::Vector2d> points_;
};

// Smooth terrain: a sum of three plane waves of 50-200 m wavelength; |z| <= amplitude.
class Terrain {
 public:
  Terrain(double amplitude, Rng& rng) : amplitude_(amplitude) {
    for (Wave& wave : waves_) {
      const double wavenumber = 2 * M_PI / Uniform(rng, 50.0, 200.0);  // rad/m
      const double direction = Uniform(rng, -M_PI, M_PI);
      wave.k = wavenumber * Eigen::Vector2d(std::cos(direction), std::sin(direction));
      wave.phase = Uniform(rng, -M_PI, M_PI);
    }
  }
  double Height(const Eigen::Vector2d& p) const {
    if (amplitude_ == 0) return 0;
    double z = 0;
    for (const Wave& wave : waves_) z += std::sin(wave.k.dot(p) + wave.phase);
    return z * amplitude_ / waves_.size();
  }

 private:
  struct Wave {
    Eigen::Vector2d k;  // rad/m
    double phase;       // rad
  };
  double amplitude_;
  std::array<Wave, 3> waves_;
};

// Thomas-process fit to the border-corrected excess neighbour count (Ripley's K, Illian et al.
// 2008 eq. 4.3.30): E(r) = lambda K(r) - lambda pi r^2 = A (1 - exp(-r^2 / (4 sigma^2))).
struct ClusterFit {
  double excess = 0;  // A, extra neighbours of a typical tree due to clustering
  double sigma = 3;   // m
};

ClusterFit FitClusterTerm(const std::vector<MapTree>& trees, const TreeGrid& grid,
                          const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double density) {
  constexpr int kRadii = 16;
  const double r_max = std::min(20.0, (hi - lo).minCoeff() / 4);
  if (r_max < 1.0) return {};
  const double bin = r_max / kRadii;
  std::vector<double> neighbours(kRadii + 1, 0.0), focal(kRadii + 1, 0.0);
  const size_t stride = std::max<size_t>(1, trees.size() / kMaxFocalTrees);
  for (size_t i = 0; i < trees.size(); i += stride) {
    const Eigen::Vector2d p = trees[i].position.head<2>();
    const double border = std::min((p - lo).minCoeff(), (hi - p).minCoeff());
    std::array<int, kRadii + 1> histogram{};
    for (int j : grid.InRadius(p, r_max)) {
      if (j == static_cast<int>(i)) continue;
      const double d = (trees[j].position.head<2>() - p).norm();
      ++histogram[std::clamp(static_cast<int>(std::ceil(d / bin)), 1, kRadii)];
    }
    int cumulative = 0;
    for (int k = 1; k <= kRadii && k * bin <= border; ++k) {
      cumulative += histogram[k];
      neighbours[k] += cumulative;
      focal[k] += 1;
    }
  }
  std::vector<double> r, excess, weight;
  for (int k = 1; k <= kRadii; ++k) {
    if (focal[k] < 10) continue;
    r.push_back(k * bin);
    excess.push_back(neighbours[k] / focal[k] - density * M_PI * r.back() * r.back());
    weight.push_back(focal[k] / (1 + density * M_PI * r.back() * r.back()));  // 1 / variance
  }
  ClusterFit best;
  double best_residual = std::numeric_limits<double>::infinity();
  for (double sigma = 0.25; sigma <= r_max / 2; sigma *= 1.15) {
    double sum_em = 0, sum_mm = 0;
    std::vector<double> model(r.size());
    for (size_t k = 0; k < r.size(); ++k) {
      model[k] = 1 - std::exp(-r[k] * r[k] / (4 * sigma * sigma));
      sum_em += weight[k] * excess[k] * model[k];
      sum_mm += weight[k] * model[k] * model[k];
    }
    if (sum_mm <= 0) continue;
    const double amplitude = std::max(0.0, sum_em / sum_mm);
    double residual = 0;
    for (size_t k = 0; k < r.size(); ++k) {
      residual += weight[k] * std::pow(excess[k] - amplitude * model[k], 2);
    }
    if (residual < best_residual) best_residual = residual, best = {amplitude, sigma};
  }
  return best;
}

// Roll and pitch uniform in [-max_tilt, max_tilt], kept when the z axis tilts <= max_tilt.
std::pair<double, double> DrawTilt(double max_tilt, Rng& rng) {
  if (max_tilt <= 0) return {0.0, 0.0};
  while (true) {
    const double roll = Uniform(rng, -max_tilt, max_tilt);
    const double pitch = Uniform(rng, -max_tilt, max_tilt);
    if (std::cos(roll) * std::cos(pitch) >= std::cos(max_tilt)) return {roll, pitch};
  }
}

// A unit vector within ~sd rad (per axis) of `direction`.
Eigen::Vector3d PerturbDirection(const Eigen::Vector3d& direction, double sd, Rng& rng) {
  const Eigen::Vector3d u = direction.unitOrthogonal();
  const Eigen::Vector3d v = direction.cross(u);
  return (direction + Gaussian(rng, sd) * u + Gaussian(rng, sd) * v).normalized();
}

// The view with its detections (and their truth ids) in random order: a detector's output order
// must not reveal which detections are true or near.
SimulatedView Shuffled(const SimulatedView& view, Rng& rng) {
  std::vector<size_t> order(view.trees.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  SimulatedView shuffled{view.map_from_sensor, {}, {}, view.visible_trees};
  for (size_t i : order) {
    shuffled.trees.push_back(view.trees[i]);
    shuffled.truth_ids.push_back(view.truth_ids[i]);
  }
  return shuffled;
}

}  // namespace

void StemMapStatistics::Check() const {
  Require(std::isfinite(density) && density > 0, "StemMapStatistics.density must be > 0 trees/m^2",
          density);
  Require(std::isfinite(min_spacing) && min_spacing >= 0,
          "StemMapStatistics.min_spacing must be >= 0 m", min_spacing);
  Require(density * M_PI * min_spacing * min_spacing / 4 <= kMaxHardCoreCoverage,
          "StemMapStatistics: min_spacing too large for the density (hard-core discs would cover "
          "more than 40% of the area), min_spacing",
          min_spacing);
  Require(cluster_fraction >= 0 && cluster_fraction <= 1,
          "StemMapStatistics.cluster_fraction must be in [0, 1]", cluster_fraction);
  Require(std::isfinite(cluster_radius) && cluster_radius > 0,
          "StemMapStatistics.cluster_radius must be > 0 m", cluster_radius);
  Require(std::isfinite(cluster_size) && cluster_size >= 1,
          "StemMapStatistics.cluster_size must be >= 1 tree", cluster_size);
  Require(std::isfinite(dbh_log_mean), "StemMapStatistics.dbh_log_mean must be finite",
          dbh_log_mean);
  Require(std::isfinite(dbh_log_sd) && dbh_log_sd >= 0, "StemMapStatistics.dbh_log_sd must be >= 0",
          dbh_log_sd);
}

void ForestOptions::Check() const {
  Require(std::isfinite(width) && width > 0, "ForestOptions.width must be > 0 m", width);
  Require(std::isfinite(height) && height > 0, "ForestOptions.height must be > 0 m", height);
  Require(std::isfinite(z_amplitude) && z_amplitude >= 0,
          "ForestOptions.z_amplitude must be >= 0 m", z_amplitude);
}

void ViewOptions::Check() const {
  Require(std::isfinite(range) && range > 0, "ViewOptions.range must be > 0 m", range);
  Require(miss_rate >= 0 && miss_rate <= 1, "ViewOptions.miss_rate must be in [0, 1]", miss_rate);
  Require(std::isfinite(false_rate) && false_rate >= 0, "ViewOptions.false_rate must be >= 0",
          false_rate);
  Require(std::isfinite(position_noise) && position_noise >= 0,
          "ViewOptions.position_noise must be >= 0 m", position_noise);
  Require(std::isfinite(dbh_noise) && dbh_noise >= 0, "ViewOptions.dbh_noise must be >= 0 m",
          dbh_noise);
  Require(std::isfinite(axis_noise) && axis_noise >= 0, "ViewOptions.axis_noise must be >= 0 rad",
          axis_noise);
  Require(max_tilt >= 0 && max_tilt <= kMaxTilt, "ViewOptions.max_tilt must be in [0, 1.5] rad",
          max_tilt);
  Require(std::isfinite(sensor_height), "ViewOptions.sensor_height must be finite m",
          sensor_height);
}

TreeGrid::TreeGrid(const std::vector<MapTree>& trees) {
  if (trees.empty()) return;
  min_corner_ = max_corner_ = trees.front().position.head<2>();
  for (const MapTree& tree : trees) {
    if (!tree.position.head<2>().allFinite()) {
      Invalid("TreeGrid: tree " + std::to_string(tree.id) + " has a non-finite x or y, x",
              tree.position.x());
    }
    min_corner_ = min_corner_.cwiseMin(tree.position.head<2>());
    max_corner_ = max_corner_.cwiseMax(tree.position.head<2>());
  }
  const Eigen::Vector2d extent = (max_corner_ - min_corner_).cwiseMax(1e-3);
  const double n = static_cast<double>(trees.size());
  cell_size_ = std::max(std::sqrt(extent.prod() * 2 / n), 1e-3);  // ~2 trees per cell
  while ((extent.x() / cell_size_ + 1) * (extent.y() / cell_size_ + 1) > 4 * n + 64) {
    cell_size_ *= 1.5;  // thin, elongated extents: bound the number of cells
  }
  nx_ = static_cast<int>(extent.x() / cell_size_) + 1;
  ny_ = static_cast<int>(extent.y() / cell_size_) + 1;
  std::vector<int> cell_of(trees.size());
  cell_start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (size_t i = 0; i < trees.size(); ++i) {
    cell_of[i] = CellY(trees[i].position.y()) * nx_ + CellX(trees[i].position.x());
    ++cell_start_[cell_of[i] + 1];
  }
  std::partial_sum(cell_start_.begin(), cell_start_.end(), cell_start_.begin());
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  index_.resize(trees.size());
  xy_.resize(trees.size());
  for (size_t i = 0; i < trees.size(); ++i) {
    const int slot = fill[cell_of[i]]++;
    index_[slot] = static_cast<int>(i);
    xy_[slot] = trees[i].position.head<2>();
  }
}

int TreeGrid::CellX(double x) const {
  return static_cast<int>(std::clamp(std::floor((x - min_corner_.x()) / cell_size_), 0.0,
                                     static_cast<double>(nx_ - 1)));
}

int TreeGrid::CellY(double y) const {
  return static_cast<int>(std::clamp(std::floor((y - min_corner_.y()) / cell_size_), 0.0,
                                     static_cast<double>(ny_ - 1)));
}

std::vector<int> TreeGrid::InRadius(const Eigen::Vector2d& center, double radius) const {
  std::vector<int> result;
  if (nx_ == 0 || !(radius >= 0)) return result;
  const int x0 = CellX(center.x() - radius), x1 = CellX(center.x() + radius);
  const int y0 = CellY(center.y() - radius), y1 = CellY(center.y() + radius);
  for (int y = y0; y <= y1; ++y) {
    for (int slot = cell_start_[y * nx_ + x0]; slot < cell_start_[y * nx_ + x1 + 1]; ++slot) {
      if ((xy_[slot] - center).squaredNorm() <= radius * radius) result.push_back(index_[slot]);
    }
  }
  return result;
}

int TreeGrid::Nearest(const Eigen::Vector2d& center, int exclude) const {
  if (nx_ == 0) return -1;
  const int cx = CellX(center.x()), cy = CellY(center.y());
  int best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  auto visit = [&](int x, int y) {
    for (int slot = cell_start_[y * nx_ + x]; slot < cell_start_[y * nx_ + x + 1]; ++slot) {
      const double d2 = (xy_[slot] - center).squaredNorm();
      if (index_[slot] != exclude && d2 < best_d2) best_d2 = d2, best = index_[slot];
    }
  };
  // Rings of cells at Chebyshev distance k; trees beyond ring k are >= k cells away.
  for (int k = 0; k <= std::max(nx_, ny_); ++k) {
    for (int y = std::max(cy - k, 0); y <= std::min(cy + k, ny_ - 1); ++y) {
      const bool full_row = std::abs(y - cy) == k;
      for (int x = cx - k; x <= cx + k; x += (full_row ? 1 : 2 * k)) {
        if (x >= 0 && x < nx_) visit(x, y);
        if (k == 0) break;
      }
    }
    if (best >= 0 && std::sqrt(best_d2) <= k * cell_size_) break;
  }
  return best;
}

StemMapStatistics EstimateStemMapStatistics(const std::vector<MapTree>& trees) {
  if (trees.size() < 10) {
    Invalid("EstimateStemMapStatistics needs >= 10 trees", static_cast<double>(trees.size()));
  }
  const TreeGrid grid(trees);
  const Eigen::Vector2d extent = grid.max_corner() - grid.min_corner();
  if (extent.minCoeff() <= 0) Invalid("EstimateStemMapStatistics: degenerate extent, m", 0.0);
  // Unbiased window of n uniform points: the bounding box grown by (n+1)/(n-1) per axis.
  const double n = static_cast<double>(trees.size());
  const Eigen::Vector2d margin = extent * (1.0 / (n - 1));
  const Eigen::Vector2d lo = grid.min_corner() - margin, hi = grid.max_corner() + margin;
  StemMapStatistics stats;
  stats.density = n / (hi - lo).prod();

  std::vector<double> nn_distances;
  const size_t stride = std::max<size_t>(1, trees.size() / kMaxFocalTrees);
  for (size_t i = 0; i < trees.size(); i += stride) {
    const Eigen::Vector2d p = trees[i].position.head<2>();
    const int j = grid.Nearest(p, static_cast<int>(i));
    nn_distances.push_back((trees[j].position.head<2>() - p).norm());
  }
  const auto percentile_1 = nn_distances.begin() + nn_distances.size() / 100;
  std::nth_element(nn_distances.begin(), percentile_1, nn_distances.end());
  stats.min_spacing = *percentile_1;

  const ClusterFit fit = FitClusterTerm(trees, grid, lo, hi, stats.density);
  if (fit.excess >= kMinClusterExcess) {
    stats.cluster_radius = fit.sigma;
    stats.cluster_fraction = std::min(1.0, fit.excess / stats.cluster_size);
    stats.cluster_size = std::max(stats.cluster_size, fit.excess);
  }

  std::vector<double> log_dbh;
  for (const MapTree& tree : trees) {
    if (IsKnown(tree.dbh) && tree.dbh > 0 && std::isfinite(tree.dbh)) {
      log_dbh.push_back(std::log(tree.dbh));
    }
  }
  stats.has_dbh = log_dbh.size() >= 2 && 2 * log_dbh.size() >= trees.size();
  if (stats.has_dbh) {
    const double mean = std::accumulate(log_dbh.begin(), log_dbh.end(), 0.0) / log_dbh.size();
    double sum_sq = 0;
    for (double v : log_dbh) sum_sq += (v - mean) * (v - mean);
    stats.dbh_log_mean = mean;
    stats.dbh_log_sd = std::sqrt(sum_sq / (log_dbh.size() - 1));
  }
  // Keep the result generable even for maps with near-duplicate or very crowded trees.
  const double max_spacing = std::sqrt(4 * kMaxHardCoreCoverage / (M_PI * stats.density));
  stats.min_spacing = std::min(stats.min_spacing, max_spacing);
  return stats;
}

std::vector<MapTree> GenerateForest(const StemMapStatistics& stats, const ForestOptions& options) {
  stats.Check();
  options.Check();
  const double expected = stats.density * options.width * options.height;
  Require(expected <= kMaxGeneratedTrees, "GenerateForest: more than 1e8 trees requested",
          expected);
  const int64_t n = std::llround(expected);
  const int64_t n_clustered = std::llround(stats.cluster_fraction * static_cast<double>(n));
  Rng rng(options.seed);
  const Terrain terrain(options.z_amplitude, rng);
  HardCoreGrid placed(options.width, options.height, stats.min_spacing, stats.density);
  std::uniform_real_distribution<double> along_x(0.0, options.width), along_y(0.0, options.height);

  for (int64_t i = 0; i < n - n_clustered; ++i) {
    for (int t = 0; t < kMaxPlacementTries; ++t) {
      if (placed.TryInsert({along_x(rng), along_y(rng)})) break;
    }
  }
  if (n_clustered > 0) {
    const int64_t n_parents =
        std::max<int64_t>(1, std::llround(static_cast<double>(n_clustered) / stats.cluster_size));
    std::vector<Eigen::Vector2d> parents(n_parents);
    for (Eigen::Vector2d& parent : parents) parent = {along_x(rng), along_y(rng)};
    std::uniform_int_distribution<int64_t> pick(0, n_parents - 1);
    for (int64_t i = 0; i < n_clustered; ++i) {
      const Eigen::Vector2d& parent = parents[pick(rng)];
      for (int t = 0; t < kMaxPlacementTries; ++t) {
        Eigen::Vector2d p = parent + Eigen::Vector2d(Gaussian(rng, stats.cluster_radius),
                                                     Gaussian(rng, stats.cluster_radius));
        p = {WrapInto(p.x(), options.width), WrapInto(p.y(), options.height)};
        if (placed.TryInsert(p)) break;
      }
    }
  }

  std::vector<MapTree> trees(placed.points().size());
  std::normal_distribution<double> log_dbh(stats.dbh_log_mean, std::max(stats.dbh_log_sd, 1e-12));
  for (size_t i = 0; i < trees.size(); ++i) {
    const Eigen::Vector2d& p = placed.points()[i];
    trees[i].id = static_cast<int64_t>(i);
    trees[i].position = Eigen::Vector3d(p.x(), p.y(), terrain.Height(p));
    if (stats.has_dbh) trees[i].dbh = std::clamp(std::exp(log_dbh(rng)), 0.02, 2.0);
  }
  return trees;
}

ViewSimulator::ViewSimulator(std::vector<MapTree> map) : map_(std::move(map)), grid_(map_) {}

std::vector<int> ViewSimulator::VisibleTrees(const Eigen::Vector2d& position_xy, double range,
                                             bool occlusion) const {
  struct Candidate {
    int index;
    double distance, bearing, half_angle;  // m, rad, rad
  };
  std::vector<Candidate> candidates;
  for (int i : grid_.InRadius(position_xy, range)) {
    const Eigen::Vector2d offset = map_[i].position.head<2>() - position_xy;
    const double distance = offset.norm();
    const double dbh = map_[i].dbh;
    const double radius = IsKnown(dbh) && dbh > 0 ? dbh / 2 : kUnknownDbhRadius;
    if (distance <= radius) continue;  // the sensor cannot be inside a trunk: skip that tree
    candidates.push_back(
        {i, distance, std::atan2(offset.y(), offset.x()), std::asin(radius / distance)});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return a.distance != b.distance ? a.distance < b.distance : a.index < b.index;
  });
  std::vector<int> visible;
  ShadowSet shadows;
  for (const Candidate& c : candidates) {
    if (!occlusion) {
      visible.push_back(c.index);
      continue;
    }
    if (!shadows.Covers(c.bearing)) visible.push_back(c.index);
    shadows.Add(c.bearing - c.half_angle, c.bearing + c.half_angle);  // hidden trunks cast too
  }
  return visible;
}

SimulatedView ViewSimulator::Simulate(const Eigen::Vector2d& position_xy, double yaw,
                                      const ViewOptions& options) const {
  options.Check();
  Require(position_xy.allFinite(), "ViewSimulator::Simulate: position must be finite, x",
          position_xy.x());
  Require(std::isfinite(yaw), "ViewSimulator::Simulate: yaw must be finite rad", yaw);
  Rng rng(options.seed);
  auto ground_z = [&](const Eigen::Vector2d& p) {
    const int nearest = grid_.Nearest(p);
    return nearest >= 0 && IsKnown(map_[nearest].position.z()) ? map_[nearest].position.z() : 0.0;
  };
  SimulatedView view;
  const auto [roll, pitch] = DrawTilt(options.max_tilt, rng);
  view.map_from_sensor.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                      .toRotationMatrix();
  view.map_from_sensor.translation() = Eigen::Vector3d(
      position_xy.x(), position_xy.y(), ground_z(position_xy) + options.sensor_height);
  const Pose3 sensor_from_map = view.map_from_sensor.inverse();
  const Eigen::Vector3d up_in_sensor = sensor_from_map.linear() * Eigen::Vector3d::UnitZ();

  std::bernoulli_distribution missed(options.miss_rate);
  auto detect = [&](Eigen::Vector3d map_point, double dbh, int64_t truth_id) {
    for (int a = 0; a < 3; ++a) map_point[a] += Gaussian(rng, options.position_noise);
    DetectedTree tree;
    tree.position = sensor_from_map * map_point;
    if (IsKnown(dbh)) tree.dbh = std::max(kMinDetectedDbh, dbh + Gaussian(rng, options.dbh_noise));
    tree.axis = PerturbDirection(up_in_sensor, options.axis_noise, rng);
    tree.score = Uniform(rng, 0.5, 1.0);  // uninformative: false stems score alike
    view.trees.push_back(tree);
    view.truth_ids.push_back(truth_id);
  };

  const std::vector<int> visible = VisibleTrees(position_xy, options.range, options.occlusion);
  view.visible_trees = static_cast<int>(visible.size());
  for (int i : visible) {
    if (missed(rng)) continue;
    const MapTree& tree = map_[i];
    const double z = IsKnown(tree.position.z()) ? tree.position.z() : 0.0;
    detect({tree.position.x(), tree.position.y(), z}, tree.dbh, tree.id);
  }

  const double expected_false = options.false_rate * static_cast<double>(view.trees.size());
  const int n_false = expected_false > 0 ? std::poisson_distribution<int>(expected_false)(rng) : 0;
  std::uniform_int_distribution<size_t> any_tree(0, map_.empty() ? 0 : map_.size() - 1);
  for (int f = 0; f < n_false; ++f) {
    for (int t = 0; t < kMaxPlacementTries; ++t) {
      const double r = options.range * std::sqrt(Uniform(rng, 0.0, 1.0));
      const double bearing = Uniform(rng, -M_PI, M_PI);
      const Eigen::Vector2d p =
          position_xy + r * Eigen::Vector2d(std::cos(bearing), std::sin(bearing));
      if (!grid_.InRadius(p, kFalseStemClearance).empty()) continue;
      detect({p.x(), p.y(), ground_z(p)}, map_.empty() ? kUnknown : map_[any_tree(rng)].dbh, -1);
      break;
    }
  }

  return Shuffled(view, rng);
}

std::vector<Eigen::Vector3d> ViewSimulator::SamplePoses(int count, double margin, unsigned seed,
                                                        int min_trees, double range) const {
  Require(count >= 0, "SamplePoses: count must be >= 0", count);
  Require(std::isfinite(margin) && margin >= 0, "SamplePoses: margin must be >= 0 m", margin);
  Require(std::isfinite(range) && range > 0, "SamplePoses: range must be > 0 m", range);
  Require(min_trees >= 0, "SamplePoses: min_trees must be >= 0", min_trees);
  Require(!map_.empty(), "SamplePoses: the map is empty, trees", 0);
  const Eigen::Vector2d lo = grid_.min_corner().array() + margin;
  const Eigen::Vector2d hi = grid_.max_corner().array() - margin;
  Require(lo.x() <= hi.x() && lo.y() <= hi.y(),
          "SamplePoses: margin leaves no room inside the map's extent, margin", margin);
  Rng rng(seed);
  std::vector<Eigen::Vector3d> poses;
  const int64_t max_draws = 1000 * static_cast<int64_t>(count);
  for (int64_t draw = 0; draw < max_draws && static_cast<int>(poses.size()) < count; ++draw) {
    const Eigen::Vector2d p(Uniform(rng, lo.x(), std::nextafter(hi.x(), INFINITY)),
                            Uniform(rng, lo.y(), std::nextafter(hi.y(), INFINITY)));
    const double yaw = Uniform(rng, -M_PI, M_PI);
    if (min_trees > 0 && static_cast<int>(grid_.InRadius(p, range).size()) < min_trees) continue;
    poses.emplace_back(p.x(), p.y(), yaw);
  }
  return poses;
}

std::vector<Eigen::Vector3d> SamplePoses(const std::vector<MapTree>& map, int count, double margin,
                                         unsigned seed, int min_trees, double range) {
  return ViewSimulator(map).SamplePoses(count, margin, seed, min_trees, range);
}

}  // namespace forestmap::algorithms
