#pragma once

#include <cstdint>
#include <random>

namespace forestmap::algorithms {

// The generator every seeded algorithm owns (options carry the seed; no global state).
using Rng = std::mt19937_64;

// A uniform draw from [lo, hi).
inline double Uniform(Rng& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// SplitMix64's finaliser: a stateless hash, for draws that must be the same however often (and
// in whichever order) they are made.
inline uint64_t SplitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Rejection sampling: draws per placed item (a tree, a false stem) before giving up on it.
inline constexpr int kMaxPlacementTries = 100;

// A zero-mean normal draw with standard deviation `sd`; exactly 0 (and no draw) when sd <= 0.
inline double Gaussian(Rng& rng, double sd) {
  return sd > 0 ? std::normal_distribution<double>(0.0, sd)(rng) : 0.0;
}

}  // namespace forestmap::algorithms
