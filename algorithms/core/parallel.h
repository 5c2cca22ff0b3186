#pragma once

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace forestmap::algorithms {

// `requested` threads, or one per hardware thread when requested <= 0.
inline int ThreadCount(int requested) {
  if (requested > 0) return requested;
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

// Runs fn(chunk, begin, end) over [0, n) split into `chunks` contiguous ranges, one thread each
// (on the calling thread when chunks <= 1). Chunk k covers [n*k/chunks, n*(k+1)/chunks), so the
// split, and with it any per-chunk result, depends only on n and chunks.
template <typename Fn>
void ParallelFor(size_t n, int chunks, Fn fn) {
  if (chunks <= 1) return fn(0, size_t{0}, n);
  std::vector<std::thread> pool;
  pool.reserve(chunks);
  for (int t = 0; t < chunks; ++t) {
    pool.emplace_back([&, t] { fn(t, n * t / chunks, n * (t + 1) / chunks); });
  }
  for (auto& thread : pool) thread.join();
}

}  // namespace forestmap::algorithms
