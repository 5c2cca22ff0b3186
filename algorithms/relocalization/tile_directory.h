#pragma once
// Which stored tile holds a square tile of a grid, by its integer tile coordinates: a dense
// directory over the tiles' bounding box, or a flat hash table (open addressing, linear probing)
// when that box is mostly empty, so memory follows the tiles, not the grid's extent. Shared by
// the occupancy grid and the coverage grid.

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace forestmap::algorithms {

// floor(v) as an integer cell index, inline (std::floor is a library call on baseline x86-64,
// and the lookups that use this run millions of times a query). |v| < 2^62.
inline int64_t FloorCell(double v) {
  const int64_t i = static_cast<int64_t>(v);
  return i - (v < static_cast<double>(i));
}

class TileDirectory {
 public:
  static uint64_t Key(int64_t tx, int64_t ty) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(tx)) << 32) | static_cast<uint32_t>(ty);
  }

  // `entries`: (tile key, stored tile index >= 0), sorted by key, each key once.
  void Index(const std::vector<std::pair<uint64_t, int32_t>>& entries);

  // The stored tile's index, -1 when there is none.
  int32_t Find(uint64_t key) const {
    if (!directory_.empty()) {
      const int64_t tx = static_cast<int32_t>(key >> 32) - min_tx_;
      const int64_t ty = static_cast<int32_t>(key & 0xFFFFFFFFu) - min_ty_;
      if (tx < 0 || ty < 0 || tx >= width_ || ty >= height_) return -1;
      return directory_[ty * width_ + tx];
    }
    if (hash_.empty()) return -1;
    size_t i = (key * 0x9E3779B97F4A7C15ull) >> 17 & mask_;
    while (hash_[i].tile >= 0) {
      if (hash_[i].key == key) return hash_[i].tile;
      i = (i + 1) & mask_;
    }
    return -1;
  }

  size_t MemoryBytes() const {
    return directory_.capacity() * sizeof(int32_t) + hash_.capacity() * sizeof(HashEntry);
  }

 private:
  struct HashEntry {
    uint64_t key = 0;
    int32_t tile = -1;  // -1 = free
  };
  std::vector<int32_t> directory_;  // dense: tile index by (ty - min_ty_, tx - min_tx_), -1 = none
  int64_t min_tx_ = 0, min_ty_ = 0, width_ = 0, height_ = 0;
  std::vector<HashEntry> hash_;  // sparse
  size_t mask_ = 0;
};

}  // namespace forestmap::algorithms
