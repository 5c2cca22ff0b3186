#include "server/app/map_union.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "server/app/errors.h"
#include "server/app/map_crs.h"
#include "server/app/tree_records.h"

namespace forestmap::server {
namespace {

constexpr double kMaxSameTree = 1.0;  // m, the grid below looks one cell around

// The union's trees so far on a grid of kMaxSameTree cells, to find a later map's tree that an
// earlier map holds already.
class TreeGrid {
 public:
  bool HeldByAnother(const algorithms::MapTree& tree, uint32_t member,
                     const std::vector<algorithms::MapTree>& trees,
                     const std::vector<MapUnion::Origin>& origin) const {
    const int64_t cx = Cell(tree.position.x()), cy = Cell(tree.position.y());
    for (int64_t dx = -1; dx <= 1; ++dx) {
      for (int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = cells_.find(Key(cx + dx, cy + dy));
        if (it == cells_.end()) continue;
        for (const uint32_t i : it->second) {
          if (origin[i].member == member) continue;
          const double reach = std::isnan(tree.dbh) || std::isnan(trees[i].dbh)
                                   ? kSameTree
                                   : std::max(kSameTree, (tree.dbh + trees[i].dbh) / 2);
          const double apart = (trees[i].position.head<2>() - tree.position.head<2>()).norm();
          if (apart < std::min(reach, kMaxSameTree)) return true;
        }
      }
    }
    return false;
  }
  void Add(const algorithms::MapTree& tree, uint32_t i) {
    cells_[Key(Cell(tree.position.x()), Cell(tree.position.y()))].push_back(i);
  }

 private:
  static int64_t Cell(double v) { return static_cast<int64_t>(std::floor(v / kMaxSameTree)); }
  static uint64_t Key(int64_t cx, int64_t cy) {
    return (static_cast<uint64_t>(cx) << 32) ^ static_cast<uint32_t>(cy);
  }
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells_;
};

}  // namespace

size_t MapUnion::MostMatched(const std::vector<algorithms::TreeMatch>& matches) const {
  std::vector<int> count(members.size(), 0);
  for (const algorithms::TreeMatch& match : matches) ++count[origin.at(match.map_tree_id).member];
  return static_cast<size_t>(std::max_element(count.begin(), count.end()) - count.begin());
}

MapUnion BuildMapUnion(storage::MapStore& store, const std::vector<storage::MapInfo>& maps,
                       const algorithms::MapIndexOptions& options) {
  MapUnion out;
  std::vector<algorithms::MapTree> trees;
  std::vector<algorithms::Polygon> coverage;
  std::vector<std::vector<algorithms::MapTree>> unbounded;  // trees of each map without boundary
  bool any_boundary = false;
  TreeGrid grid;
  for (const storage::MapInfo& info : maps) {
    const storage::MapSnapshot snapshot = store.ReadMap(info.name);
    const auto member = static_cast<uint32_t>(out.members.size());
    out.members.push_back({info.name, snapshot.info.version, snapshot.info.created_unix_ms});
    std::vector<algorithms::MapTree> own;
    for (const storage::TreeRecord& record : snapshot.trees) {
      if (record.status == storage::TreeStatus::kConfirmed) own.push_back(ToMapTree(record));
    }
    std::vector<algorithms::Polygon> boundary = ToPolygons(snapshot.boundary);
    any_boundary = any_boundary || !boundary.empty();
    coverage.insert(coverage.end(), boundary.begin(), boundary.end());
    for (const algorithms::MapTree& tree : own) {
      if (grid.HeldByAnother(tree, member, trees, out.origin)) continue;
      const auto id = static_cast<uint32_t>(trees.size());
      out.origin.push_back({member, tree.id});
      trees.push_back(tree);
      trees.back().id = id;
      grid.Add(tree, id);
    }
    if (boundary.empty()) unbounded.push_back(std::move(own));
  }
  if (trees.empty()) {
    throw PreconditionError("none of the " + std::to_string(maps.size()) +
                            " maps has confirmed trees; upload trees before relocalizing");
  }
  try {
    if (any_boundary) {
      for (const std::vector<algorithms::MapTree>& own : unbounded) {
        std::vector<algorithms::Polygon> derived = algorithms::DerivedCoverage(own, options);
        coverage.insert(coverage.end(), derived.begin(), derived.end());
      }
    }
    out.index =
        std::make_shared<const algorithms::MapIndex>(std::move(trees), options, std::move(coverage));
  } catch (const std::invalid_argument& e) {
    throw PreconditionError("the " + std::to_string(maps.size()) + " maps from \"" +
                            maps.front().name + "\" cannot be indexed together: " + e.what());
  }
  out.to_wgs84 = AnswersToWgs84(maps.front().crs);
  return out;
}

MapUnionCache::MapUnionCache(storage::MapStore& store, algorithms::MapIndexOptions options,
                             int max_entries)
    : store_(store), options_(std::move(options)), max_entries_(std::max(1, max_entries)) {}

std::shared_ptr<const MapUnion> MapUnionCache::Get(std::vector<storage::MapInfo> maps) {
  std::sort(maps.begin(), maps.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  std::string key;
  for (const storage::MapInfo& info : maps) {
    key += info.name + '\0' + std::to_string(info.version) + '\0' +
           std::to_string(info.created_unix_ms) + '\0';
  }
  std::promise<std::shared_ptr<const MapUnion>> promise;
  std::shared_future<std::shared_ptr<const MapUnion>> other;  // a ready or building union
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = slots_.find(key);
    if (it != slots_.end()) {
      lru_.splice(lru_.begin(), lru_, it->second.lru);
      other = it->second.union_;
    } else {
      lru_.push_front(key);
      slots_[key] = Slot{promise.get_future().share(), lru_.begin()};
      while (slots_.size() > max_entries_) EraseLocked(lru_.back());
    }
  }
  if (other.valid()) return other.get();  // rethrows that build's error
  try {
    auto built = std::make_shared<const MapUnion>(BuildMapUnion(store_, maps, options_));
    promise.set_value(built);
    return built;
  } catch (...) {
    promise.set_exception(std::current_exception());
    std::lock_guard<std::mutex> lock(mutex_);
    EraseLocked(key);  // not remembered: the next question tries again
    throw;
  }
}

size_t MapUnionCache::memory_bytes() const {
  size_t bytes = 0;
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [key, slot] : slots_) {
    if (slot.union_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) continue;
    try {
      bytes += slot.union_.get()->index->MemoryBytes();
    } catch (...) {  // a failed build, about to be dropped
    }
  }
  return bytes;
}

void MapUnionCache::EraseLocked(const std::string& key) {
  const auto it = slots_.find(key);
  if (it == slots_.end()) return;
  lru_.erase(it->second.lru);
  slots_.erase(it);
}

}  // namespace forestmap::server
