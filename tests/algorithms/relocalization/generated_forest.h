#pragma once
// A generated (Poisson, with a minimum spacing) forest for the relocalizer's tests.

#include <algorithm>
#include <cmath>
#include <vector>

#include "algorithms/simulation/forest_generator.h"

namespace forestmap::algorithms::testing_util {

// `size` x `size` m at `density` trees/m^2.
inline std::vector<MapTree> Forest(unsigned seed, double size = 200, double density = 0.05) {
  StemMapStatistics stats;
  stats.density = density;
  stats.min_spacing = std::min(1.0, 0.5 / std::sqrt(density));
  ForestOptions forest;
  forest.width = forest.height = size;
  forest.seed = seed;
  return GenerateForest(stats, forest);
}

}  // namespace forestmap::algorithms::testing_util
