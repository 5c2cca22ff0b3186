#include "server/app/map_index_cache.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <utility>

#include "server/app/errors.h"
#include "server/app/map_crs.h"
#include "server/app/tree_records.h"

namespace forestmap::server {
namespace {

bool SameMapVersion(const MapIndexCache::Entry& entry, const storage::MapInfo& info) {
  return entry.version == info.version && entry.created_unix_ms == info.created_unix_ms;
}

// Orders entries of one map name: a re-created map is newer than any version of the old one.
bool Newer(const MapIndexCache::Entry& a, const MapIndexCache::Entry& b) {
  if (a.created_unix_ms != b.created_unix_ms) return a.created_unix_ms > b.created_unix_ms;
  return a.version > b.version;
}

PreconditionError NoTrees(const std::string& name, int64_t version) {
  return PreconditionError("map \"" + name + "\" has no confirmed trees (version " +
                           std::to_string(version) +
                           "); upload trees or observe more before relocalizing");
}

}  // namespace

void MapIndexCacheOptions::Check() const {
  if (max_entries < 1 || max_unions < 1) {
    throw std::invalid_argument("MapIndexCacheOptions: max_entries and max_unions must be >= 1");
  }
  index.Check();
}

MapIndexCache::MapIndexCache(storage::MapStore& store, MapIndexCacheOptions options)
    : store_(store),
      options_((options.Check(), std::move(options))),
      unions_(store, options_.index, options_.max_unions) {}

MapIndexCache::Entry MapIndexCache::Get(const std::string& name) { return GetCounted(name, true); }

MapIndexCache::Entry MapIndexCache::Warm(const std::string& name) {
  return GetCounted(name, false);
}

MapIndexCache::Entry MapIndexCache::GetCounted(const std::string& name, bool count) {
  const storage::MapInfo info = CurrentInfo(name);
  std::promise<Entry> promise;
  Lookup lookup = LookUp(name, info, promise, count);
  if (lookup.ready) return *std::move(lookup.ready);
  if (lookup.other_build.valid()) return lookup.other_build.get();  // rethrows that build's error
  return BuildAndPublish(name, info.version, lookup.build_id, promise);
}

storage::MapInfo MapIndexCache::CurrentInfo(const std::string& name) {
  storage::MapInfo info;
  try {
    info = store_.GetMap(name);
  } catch (const storage::StorageError& e) {
    if (e.code() == storage::StorageError::Code::kNotFound) Evict(name);
    throw;
  }
  if (info.confirmed_count == 0) throw NoTrees(name, info.version);
  return info;
}

MapIndexCache::Lookup MapIndexCache::LookUp(const std::string& name, const storage::MapInfo& info,
                                            std::promise<Entry>& promise, bool count) {
  std::lock_guard<std::mutex> lock(mutex_);
  Slot& slot = SlotLocked(name);
  Lookup lookup;
  if (slot.ready && SameMapVersion(*slot.ready, info)) {
    if (count) ++stats_.hits;
    lookup.ready = *slot.ready;
    return lookup;
  }
  if (slot.failed && slot.failed_version == info.version &&
      slot.failed_created_ms == info.created_unix_ms) {
    std::rethrow_exception(slot.failed);
  }
  if (slot.building.valid() && slot.building_version == info.version &&
      slot.building_created_ms == info.created_unix_ms) {
    if (count) ++stats_.waits;
    lookup.other_build = slot.building;
    return lookup;
  }
  lookup.build_id = next_build_id_++;
  slot.building = promise.get_future().share();
  slot.building_id = lookup.build_id;
  slot.building_version = info.version;
  slot.building_created_ms = info.created_unix_ms;
  ++stats_.builds;
  return lookup;
}

MapIndexCache::Entry MapIndexCache::BuildAndPublish(const std::string& name, int64_t version,
                                                    uint64_t build_id,
                                                    std::promise<Entry>& promise) {
  try {
    const auto build_start = std::chrono::steady_clock::now();
    Entry entry = BuildEntry(name);
    const std::chrono::duration<double> build_time = std::chrono::steady_clock::now() - build_start;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stats_.build_seconds += build_time.count();
    }
    Publish(name, build_id, &entry);
    promise.set_value(entry);
    return entry;
  } catch (const std::invalid_argument& e) {
    // The trees themselves cannot be indexed: an error of this map version, not of the server.
    const std::exception_ptr error = std::make_exception_ptr(PreconditionError(
        "map \"" + name + "\" (version " + std::to_string(version) +
        ") cannot be indexed: " + e.what() + "; replace its trees or restore an earlier version"));
    RememberFailure(name, build_id, error);
    Publish(name, build_id, nullptr);
    promise.set_exception(error);
    std::rethrow_exception(error);
  } catch (...) {
    Publish(name, build_id, nullptr);
    promise.set_exception(std::current_exception());
    throw;
  }
}

MapIndexCache::Entry MapIndexCache::BuildEntry(const std::string& name) const {
  // The snapshot may be newer than the MapInfo Get looked at; the entry says which it is.
  // Only confirmed trees: candidates are too uncertain to anchor a pose.
  storage::MapSnapshot snapshot = store_.ReadMap(name);
  std::vector<algorithms::MapTree> trees;
  trees.reserve(snapshot.trees.size());
  for (const storage::TreeRecord& tree : snapshot.trees) {
    if (tree.status == storage::TreeStatus::kConfirmed) trees.push_back(ToMapTree(tree));
  }
  snapshot.trees = {};  // free the records before the index allocates its own copy
  // The survey boundary, when the map has one, is what it covers (else derived from the trees).
  std::vector<algorithms::Polygon> boundary = ToPolygons(snapshot.boundary);
  if (trees.empty()) throw NoTrees(name, snapshot.info.version);
  Entry entry;
  entry.version = snapshot.info.version;
  entry.created_unix_ms = snapshot.info.created_unix_ms;
  entry.to_wgs84 = AnswersToWgs84(snapshot.info.crs);
  entry.index = std::make_shared<const algorithms::MapIndex>(std::move(trees), options_.index,
                                                             std::move(boundary));
  return entry;
}

void MapIndexCache::Publish(const std::string& name, uint64_t build_id, const Entry* entry) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = slots_.find(name);
  if (it == slots_.end()) return;  // evicted meanwhile (map deleted or trimmed)
  Slot& slot = it->second;
  if (slot.building_id == build_id) {
    slot.building = {};
    slot.building_id = 0;
  }
  if (entry != nullptr && (!slot.ready || Newer(*entry, *slot.ready))) slot.ready = *entry;
}

void MapIndexCache::RememberFailure(const std::string& name, uint64_t build_id,
                                    std::exception_ptr error) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = slots_.find(name);
  if (it == slots_.end() || it->second.building_id != build_id) return;
  it->second.failed = std::move(error);
  it->second.failed_version = it->second.building_version;
  it->second.failed_created_ms = it->second.building_created_ms;
}

MapIndexCache::Slot& MapIndexCache::SlotLocked(const std::string& name) {
  auto [it, inserted] = slots_.try_emplace(name);
  Slot& slot = it->second;
  if (!inserted) lru_.erase(slot.lru);
  lru_.push_front(name);
  slot.lru = lru_.begin();
  // Drop least recently used maps; `name` is at the front and max_entries >= 1 keeps it.
  while (slots_.size() > static_cast<size_t>(options_.max_entries)) {
    const std::string victim = lru_.back();  // a copy: erasing destroys the list's string
    EraseLocked(victim);
  }
  return slot;
}

void MapIndexCache::EraseLocked(const std::string& name) {
  const auto it = slots_.find(name);
  if (it == slots_.end()) return;
  lru_.erase(it->second.lru);
  slots_.erase(it);
}

void MapIndexCache::Evict(const std::string& name) {
  std::lock_guard<std::mutex> lock(mutex_);
  EraseLocked(name);
}

size_t MapIndexCache::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return slots_.size();
}

size_t MapIndexCache::memory_bytes() const {
  size_t bytes = unions_.memory_bytes();
  for (const auto& [name, map_bytes] : memory_bytes_by_map()) bytes += map_bytes;
  return bytes;
}

std::vector<std::pair<std::string, size_t>> MapIndexCache::memory_bytes_by_map() const {
  std::vector<std::pair<std::string, size_t>> by_map;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [name, slot] : slots_) {
      if (slot.ready) by_map.emplace_back(name, slot.ready->index->MemoryBytes());
    }
  }
  std::sort(by_map.begin(), by_map.end());
  return by_map;
}

MapIndexCache::Stats MapIndexCache::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace forestmap::server
