#include "algorithms/relocalization/tile_directory.h"

#include <algorithm>

namespace forestmap::algorithms {

void TileDirectory::Index(const std::vector<std::pair<uint64_t, int32_t>>& entries) {
  directory_.clear();
  hash_.clear();
  if (entries.empty()) return;
  int64_t max_tx = INT64_MIN, max_ty = INT64_MIN;
  min_tx_ = min_ty_ = INT64_MAX;
  for (const auto& [key, tile] : entries) {
    const int64_t tx = static_cast<int32_t>(key >> 32),
                  ty = static_cast<int32_t>(key & 0xFFFFFFFFu);
    min_tx_ = std::min(min_tx_, tx), max_tx = std::max(max_tx, tx);
    min_ty_ = std::min(min_ty_, ty), max_ty = std::max(max_ty, ty);
  }
  // Dense when the box holds at most 64 directory entries per tile (256 bytes against a tile's
  // 520): lookups then cost one memory access less.
  const double box = static_cast<double>(max_tx - min_tx_ + 1) * (max_ty - min_ty_ + 1);
  if (box <= 64.0 * entries.size()) {
    width_ = max_tx - min_tx_ + 1;
    height_ = max_ty - min_ty_ + 1;
    directory_.assign(static_cast<size_t>(box), -1);
    for (const auto& [key, tile] : entries) {
      const int64_t tx = static_cast<int32_t>(key >> 32),
                    ty = static_cast<int32_t>(key & 0xFFFFFFFFu);
      directory_[(ty - min_ty_) * width_ + (tx - min_tx_)] = tile;
    }
    return;
  }
  size_t capacity = 16;
  while (capacity < 2 * entries.size()) capacity *= 2;
  mask_ = capacity - 1;
  hash_.assign(capacity, HashEntry{});
  for (const auto& [key, tile] : entries) {
    size_t i = (key * 0x9E3779B97F4A7C15ull) >> 17 & mask_;
    while (hash_[i].tile >= 0) i = (i + 1) & mask_;
    hash_[i] = {key, tile};
  }
}

}  // namespace forestmap::algorithms
