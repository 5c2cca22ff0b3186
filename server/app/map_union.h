#pragma once
// One relocalization index over many maps of one frame (the plot maps of a district, sharing a
// CRS): a question over them searches once, at the cost of one search over their trees, however
// many maps hold them, and a view across a plot boundary matches the trees of both plots.
//
// The union holds every map's confirmed trees, except a tree of a later map (by name) within
// kSameTree (or the two trunks' radii, when larger) of an earlier map's tree: maps that overlap
// surveyed that tree twice, and two trunks cannot stand closer. What the union covers: each
// map's survey boundary, else the coverage its own trees derive (map_index.h DerivedCoverage);
// when no map of the set has a boundary, the coverage the union's trees derive (plots that touch
// become one mapped forest). The union's tree ids are places in `origin`, which names each tree's
// map and its id there.
//
// Thread-safety: MapUnionCache's methods may be called concurrently; a MapUnion is immutable.

#include <cstdint>
#include <future>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "algorithms/relocalization/map_index.h"
#include "algorithms/relocalization/relocalizer.h"
#include "geo/crs.h"
#include "storage/map_store.h"

namespace forestmap::server {

inline constexpr double kSameTree = 0.3;  // m, two maps' trees this close are one tree

struct MapUnion {
  struct Member {
    std::string name;
    int64_t version = 0;
    int64_t created_unix_ms = 0;
  };
  struct Origin {
    uint32_t member = 0;  // index into members
    int64_t id = 0;       // the tree's id in its map
  };
  std::vector<Member> members;  // by name
  std::vector<Origin> origin;   // by union tree id
  std::shared_ptr<const algorithms::MapIndex> index;
  std::shared_ptr<const geo::MapToWgs84> to_wgs84;  // the members' CRS; null when unusable

  // The member whose trees most of `matches` (union ids) are, the first of a tie; 0 for none.
  size_t MostMatched(const std::vector<algorithms::TreeMatch>& matches) const;
};

// Builds the union of `maps` (one CRS, sorted by name, unique) from their snapshots. Throws what
// the store throws, PreconditionError when no map has confirmed trees or the trees cannot be
// indexed.
MapUnion BuildMapUnion(storage::MapStore& store, const std::vector<storage::MapInfo>& maps,
                       const algorithms::MapIndexOptions& options);

// Unions built once per set of map versions and shared by concurrent questions: a build in
// progress is waited for, not repeated; beyond max_entries sets, the least recently used is
// dropped.
class MapUnionCache {
 public:
  MapUnionCache(storage::MapStore& store, algorithms::MapIndexOptions options, int max_entries = 4);

  // The union of `maps` at the versions given (a snapshot newer than one given is used as read).
  std::shared_ptr<const MapUnion> Get(std::vector<storage::MapInfo> maps);
  size_t memory_bytes() const;  // of the ready unions' indexes

 private:
  struct Slot {
    std::shared_future<std::shared_ptr<const MapUnion>> union_;
    std::list<std::string>::iterator lru;
  };
  void EraseLocked(const std::string& key);

  storage::MapStore& store_;
  algorithms::MapIndexOptions options_;
  size_t max_entries_;
  mutable std::mutex mutex_;
  std::unordered_map<std::string, Slot> slots_;
  std::list<std::string> lru_;  // most recently used first
};

}  // namespace forestmap::server
