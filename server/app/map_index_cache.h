#pragma once
// Per-map relocalization indexes, built once per map version and shared by concurrent queries.
// An index holds the CONFIRMED trees of the version only (candidates of shared maps are left out).
//
// Get(name) asks the store for the map's current MapInfo (cheap) and returns the cached index
// when it was built for that version; otherwise it builds a new one from a ReadMap snapshot.
// Builds are single-flight: concurrent Get calls for the same map version wait for the one
// build in progress instead of starting their own; Get calls for other maps are never blocked
// by a build (the cache lock is held only for lookups). Entries of deleted maps are evicted;
// beyond `max_entries` maps, the least recently used ready entry is dropped.
//
// Thread-safety: all methods may be called concurrently.

#include <cstdint>
#include <exception>
#include <future>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "algorithms/relocalization/relocalizer.h"
#include "geo/crs.h"
#include "server/app/map_union.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct MapIndexCacheOptions {
  int max_entries = 16;  // maps whose index stays in memory (>= 1)
  int max_unions = 4;    // sets of maps of one frame whose union index stays (map_union.h; >= 1)
  algorithms::MapIndexOptions index;
  void Check() const;  // throws std::invalid_argument
};

class MapIndexCache {
 public:
  struct Entry {
    std::shared_ptr<const algorithms::MapIndex> index;  // never null
    int64_t version = 0;                                // map version the index was built from
    int64_t created_unix_ms = 0;  // the map's creation time: tells a re-created map apart
    std::shared_ptr<const geo::MapToWgs84> to_wgs84;  // null when the map has no (known) CRS
  };

  struct Stats {
    int64_t builds = 0;        // indexes built (one per map version seen)
    int64_t hits = 0;          // Get answered from a ready entry
    int64_t waits = 0;         // Get that waited for another caller's build
    double build_seconds = 0;  // s, wall time of all builds (snapshot read + index), summed
  };

  MapIndexCache(storage::MapStore& store, MapIndexCacheOptions options = {});
  MapIndexCache(const MapIndexCache&) = delete;
  MapIndexCache& operator=(const MapIndexCache&) = delete;

  // The index of the map at its current version. Throws storage::StorageError kNotFound for an
  // unknown map (and evicts it), PreconditionError for a map without confirmed trees or whose
  // trees cannot be indexed (e.g. a coordinate beyond the index range, stored before validation
  // checked ranges; remembered per version, so the build is not retried until the map changes),
  // and whatever else the store or the build throws (waiters of a failed build get the same).
  Entry Get(const std::string& name);
  // The same for a preload (forestmapd --preload): builds what Get would, without counting a
  // hit or a wait in stats().
  Entry Warm(const std::string& name);

  // Indexes over the union of maps of one frame, built from the same store with the same options.
  MapUnionCache& unions() { return unions_; }

  void Evict(const std::string& name);
  size_t max_entries() const { return static_cast<size_t>(options_.max_entries); }
  size_t size() const;
  Stats stats() const;
  // Approximate memory of the ready indexes (algorithms::MapIndex::MemoryBytes), the unions'
  // included, bytes.
  size_t memory_bytes() const;
  // The same per map (ready indexes only), sorted by name.
  std::vector<std::pair<std::string, size_t>> memory_bytes_by_map() const;

 private:
  // A map's slot: the ready entry and/or the one build in progress.
  struct Slot {
    std::optional<Entry> ready;
    std::shared_future<Entry> building;  // valid while a build is in progress
    uint64_t building_id = 0;
    int64_t building_version = 0;
    int64_t building_created_ms = 0;
    std::exception_ptr failed;  // the error of the last build that cannot succeed, and its map
    int64_t failed_version = 0;
    int64_t failed_created_ms = 0;
    std::list<std::string>::iterator lru;
  };

  // What Get's lookup under the lock found: the ready entry, another caller's build of the
  // same map version to wait for, or else the id of the build this caller runs.
  struct Lookup {
    std::optional<Entry> ready;
    std::shared_future<Entry> other_build;
    uint64_t build_id = 0;
  };

  // The map's MapInfo; evicts an unknown map, throws NoTrees for one without confirmed trees.
  storage::MapInfo CurrentInfo(const std::string& name);
  // Finds the map's slot (LRU order updated); when neither a ready entry nor a build of `info`'s
  // version is there, registers a build whose result `promise` will carry. Rethrows the
  // remembered error of a version that cannot be indexed.
  Lookup LookUp(const std::string& name, const storage::MapInfo& info, std::promise<Entry>& promise,
                bool count);
  Entry GetCounted(const std::string& name, bool count);
  // Runs build `build_id` (of map version `version`), publishes its entry or error to the slot
  // and to `promise`'s waiters, and returns the entry or throws the error.
  Entry BuildAndPublish(const std::string& name, int64_t version, uint64_t build_id,
                        std::promise<Entry>& promise);
  // Reads a snapshot and builds its index (no lock held).
  Entry BuildEntry(const std::string& name) const;
  // Ends build `build_id`: stores its entry (null when it failed) if the map's slot still exists
  // and the entry is newer than the ready one.
  void Publish(const std::string& name, uint64_t build_id, const Entry* entry);
  // Remembers that the map version of build `build_id` cannot be indexed.
  void RememberFailure(const std::string& name, uint64_t build_id, std::exception_ptr error);
  Slot& SlotLocked(const std::string& name);
  void EraseLocked(const std::string& name);

  storage::MapStore& store_;
  MapIndexCacheOptions options_;
  mutable std::mutex mutex_;
  std::unordered_map<std::string, Slot> slots_;
  std::list<std::string> lru_;  // most recently used first
  uint64_t next_build_id_ = 1;
  Stats stats_;
  MapUnionCache unions_;
};

}  // namespace forestmap::server
