#pragma once

#include <random>

namespace forestmap::algorithms {

// The generator every seeded algorithm owns (options carry the seed; no global state).
using Rng = std::mt19937_64;

// A uniform draw from [lo, hi).
inline double Uniform(Rng& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// A zero-mean normal draw with standard deviation `sd`; exactly 0 (and no draw) when sd <= 0.
inline double Gaussian(Rng& rng, double sd) {
  return sd > 0 ? std::normal_distribution<double>(0.0, sd)(rng) : 0.0;
}

}  // namespace forestmap::algorithms
