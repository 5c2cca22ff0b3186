#pragma once
// The trees of one map version read page by page (MapStore::ReadTreesPage, one short read per
// page), as the export stream and the web page send them: a reader holds one page in memory
// whatever the map's size.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"
#include "storage/staged_writes.h"

namespace forestmap::server {

class TreePages {
 public:
  // The trees of version `map.version` of map `map.name` (the map as created at
  // map.created_unix_ms), `page_trees` (>= 1) a page, those inside `box` only when set. `store`
  // must outlive the reader.
  TreePages(storage::MapStore& store, const storage::MapInfo& map, int64_t page_trees,
            std::optional<storage::Extent> box = std::nullopt);

  // The next page, by increasing id; fewer than page_trees trees (maybe none) make the last one.
  // Throws the store's errors, and ServiceError kAborted when the version disappeared (the map
  // deleted or the version pruned) after the first page.
  std::vector<storage::TreeRecord> Next();

  bool done() const { return done_; }  // the last page was read

 private:
  storage::MapStore& store_;
  std::string map_name_;
  storage::TreePageQuery query_;
  bool done_ = false;
};

}  // namespace forestmap::server
