#include "algorithms/simulation/forest_generator.h"

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

#include "algorithms/core/check.h"
#include "algorithms/core/random.h"
#include "algorithms/simulation/tree_grid.h"

namespace forestmap::algorithms {

namespace {

constexpr double kMaxHardCoreCoverage = 0.4;  // RSA jams at ~0.547; stay clear of it
constexpr double kMaxGeneratedTrees = 1e8;    // guards against a typo allocating terabytes
constexpr int kMaxFocalTrees = 20000;         // trees used for the statistics of large maps
constexpr double kMinClusterExcess = 0.5;     // extra neighbours per tree deemed clustering

// `value` wrapped into [0, size): cluster offsets wrap around the area so that the intensity
// stays uniform (a torus).
double WrapInto(double value, double size) {
  return std::clamp(value - size * std::floor(value / size), 0.0, std::nextafter(size, 0.0));
}

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

StemMapStatistics EstimateStemMapStatistics(const std::vector<MapTree>& trees) {
  if (trees.size() < 10) {
    Require(false, "EstimateStemMapStatistics needs >= 10 trees",
            static_cast<double>(trees.size()));
  }
  const TreeGrid grid(trees);
  const Eigen::Vector2d extent = grid.max_corner() - grid.min_corner();
  if (extent.minCoeff() <= 0)
    Require(false, "EstimateStemMapStatistics: degenerate extent, m", 0.0);
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

}  // namespace forestmap::algorithms
