#pragma once

// Synthetic stem maps that look like a real one. GenerateForest draws a stem map from a few
// spatial statistics: a hard-core (Matern/RSA style) background plus Thomas-process clusters
// (Thomas 1949; Illian et al. 2008, "Statistical Analysis and Modelling of Spatial Point
// Patterns", sec. 6.3.2), log-normal DBH and an optional smooth terrain.
// EstimateStemMapStatistics recovers those statistics from a real map (density, the 1st
// percentile of nearest-neighbour distances, and the cluster term from Ripley's K).
// Deterministic given the seed. Frames and units as in algorithms/core/geometry.h.

#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

// Spatial statistics of a stem map, enough to generate forests that look like a real one.
struct StemMapStatistics {
  double density = 0.05;        // trees per m^2
  double min_spacing = 0.5;     // m, hard-core distance: no two trees closer than this
  double cluster_fraction = 0;  // [0, 1], share of the trees placed in Thomas clusters
  double cluster_radius = 3;    // m, sd (per axis) of a clustered tree's offset from its centre
  double cluster_size = 6;      // trees, mean number of trees per cluster (>= 1)
  double dbh_log_mean = -1.6;   // ln(m), mean of ln(DBH); used when has_dbh
  double dbh_log_sd = 0.5;      // ln(m), sd of ln(DBH); used when has_dbh
  bool has_dbh = true;          // false: generated trees have unknown (NaN) DBH
  // Throws std::invalid_argument, naming the field, for values that cannot generate a forest
  // (including hard-core discs covering more than 40% of the area, which RSA cannot fill).
  void Check() const;
};

// Estimates the statistics of a real stem map. The window is the trees' bounding box, enlarged
// by the unbiased factor (n+1)/(n-1) per axis. min_spacing is the 1st percentile of the
// nearest-neighbour distances. The cluster term fits the excess neighbour count of Ripley's K
// (border-corrected), E(r) = A (1 - exp(-r^2 / 4 sigma^2)) for a Thomas process, giving
// cluster_radius = sigma and cluster_fraction * cluster_size = A (cluster_size stays at its
// default unless A exceeds it); below A = 0.5 the map counts as unclustered (cluster fields keep
// their defaults, cluster_fraction = 0). Maps larger than 20,000 trees use a regular subsample
// of focal trees. min_spacing is capped so that the result always passes Check(). has_dbh when
// at least half of the trees have a positive DBH.
// Throws std::invalid_argument with fewer than 10 trees, a non-finite x/y, or a degenerate extent.
StemMapStatistics EstimateStemMapStatistics(const std::vector<MapTree>& trees);

struct ForestOptions {
  double width = 100;      // m, map extent along x, from x = 0
  double height = 100;     // m, map extent along y, from y = 0
  double z_amplitude = 0;  // m, max |z| of a smooth terrain (3 plane waves, 50-200 m
                           // wavelength); 0 = flat, z = 0
  unsigned seed = 1;       // random seed
  void Check() const;      // throws std::invalid_argument
};

// Generates round(density * width * height) trees with ids 0..n-1 inside [0,width) x [0,height).
// Trees that find no room after many tries (very dense hard-core) are dropped, so n can be
// smaller. DBH is log-normal, clamped to [0.02, 2] m. Cluster offsets wrap around the area's
// edges so the intensity stays uniform. Uses a grid for the hard-core test: 1,000,000 trees take
// about 0.5-1 s. Throws std::invalid_argument for invalid statistics or options.
std::vector<MapTree> GenerateForest(const StemMapStatistics& stats, const ForestOptions& options);

}  // namespace forestmap::algorithms
