#pragma once
// Stem layer extraction and clustering of the layer in the horizontal plane.
//
// The stem layer (by default 0.5-3 m above ground) holds stems and little else: below it are
// ground and litter, above it crowns and branches. Projected onto the horizontal plane, each stem
// is a dense ring or arc, which DBSCAN (Ester et al. 1996) separates with a small radius
// (Zmeškalová 2023, sec. 3.1.1: the 2-D projection is faster and more correct than 3-D clustering,
// eps 0.12 m). DBSCAN runs on a fine grid: points are binned into cells of eps * cell_fraction, a
// cell is core when the points of the cells within eps of it (cell means) reach min_points, and
// clusters are the connected core cells plus their border cells. That is exact DBSCAN up to the
// cell size and costs O(cells), not O(points * neighbours), on dense mobile-scanner clouds.
// Clusters that hold several trunks (touching stems, a stem in a shrub) are split later, by the
// per-slice circle extraction of stem_model.h.

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

namespace forestmap::algorithms {

struct StemLayerOptions {
  double min_height = 0.5;  // m above ground
  double max_height = 3.0;  // m above ground
  void Check() const;
};

// Indices of the points whose height lies in the layer. Without ground (heights relative to the
// lowest point) the layer is [0, max_height - min_height].
std::vector<uint32_t> ExtractStemLayer(std::span<const float> heights, bool ground_known,
                                       const StemLayerOptions& options);

struct StemClusterOptions {
  double eps = 0.15;            // m, DBSCAN radius in the horizontal plane
  int min_points = 5;           // points within eps of a core point (itself included)
  int min_cluster_points = 10;  // smaller clusters are noise
  double cell_fraction = 0.5;   // grid cell side = eps * cell_fraction
  void Check() const;
};

struct StemClusters {
  std::vector<std::vector<uint32_t>> clusters;  // indices into the clustered points
  size_t noise_points = 0;
  size_t cells = 0;  // occupied grid cells
};

// Clusters points[indices] by their x, y.
StemClusters ClusterStems(std::span<const Eigen::Vector3f> points,
                          std::span<const uint32_t> indices, const StemClusterOptions& options);

}  // namespace forestmap::algorithms
