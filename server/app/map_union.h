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

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <future>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
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
  std::string versions;  // the members' versions it was asked for (MapUnionCache's key)

  // The member whose trees most of `matches` (union ids) are, the first of a tie; 0 for none.
  size_t MostMatched(const std::vector<algorithms::TreeMatch>& matches) const;
};

// Builds the union of `maps` (one CRS, sorted by name, unique) from their snapshots. Throws what
// the store throws, PreconditionError when no map has confirmed trees or the trees cannot be
// indexed.
MapUnion BuildMapUnion(storage::MapStore& store, const std::vector<storage::MapInfo>& maps,
                       const algorithms::MapIndexOptions& options);

// Unions of sets of maps, shared by concurrent questions. The first question over a set builds
// its union (concurrent ones wait for that build, not start their own). When a map of the set
// changes, questions go on being answered from the union of the earlier versions (each answer
// names the versions it used) while one background thread builds the new union: a district whose
// plot maps drones keep observing into never makes a question wait for a rebuild of every map.
// Beyond max_entries sets, the least recently used is dropped.
class MapUnionCache {
 public:
  MapUnionCache(storage::MapStore& store, algorithms::MapIndexOptions options, int max_entries = 4);
  ~MapUnionCache();  // waits for a background build in progress
  MapUnionCache(const MapUnionCache&) = delete;
  MapUnionCache& operator=(const MapUnionCache&) = delete;

  // The union of `maps` (their names and versions): at those versions, or while a newer union is
  // built, at the versions of the last one built. Throws what BuildMapUnion throws when there is
  // none yet.
  std::shared_ptr<const MapUnion> Get(std::vector<storage::MapInfo> maps);
  size_t memory_bytes() const;        // of the ready unions' indexes
  int64_t background_builds() const;  // unions rebuilt after a change of their maps, so far

 private:
  struct Slot {
    std::shared_ptr<const MapUnion> ready;  // the last union built for this set of names
    std::shared_future<std::shared_ptr<const MapUnion>> first;  // the first build, in progress
    std::string queued;  // the versions a background build is on its way to; "" when none
    std::string failed;  // the versions whose build failed (not retried until they change)
    std::list<std::string>::iterator lru;
  };
  struct Job {
    std::string key;
    std::string versions;
    std::vector<storage::MapInfo> maps;
  };
  void Refresh();  // the background thread: builds the queued sets' unions
  void EraseLocked(const std::string& key);

  storage::MapStore& store_;
  algorithms::MapIndexOptions options_;
  size_t max_entries_;
  mutable std::mutex mutex_;
  std::unordered_map<std::string, Slot> slots_;  // by the set's names
  std::list<std::string> lru_;                   // most recently used first
  std::deque<Job> jobs_;
  std::condition_variable wake_;
  bool stopping_ = false;
  int64_t background_builds_ = 0;
  std::thread refresher_;  // last: started once the members above exist
};

}  // namespace forestmap::server
