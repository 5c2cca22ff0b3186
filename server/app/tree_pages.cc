#include "server/app/tree_pages.h"

#include <utility>

#include "server/app/errors.h"

namespace forestmap::server {

TreePages::TreePages(storage::MapStore& store, const storage::MapInfo& map, int64_t page_trees,
                     std::optional<storage::Extent> box)
    : store_(store), map_name_(map.name) {
  query_.version = map.version;
  query_.created_unix_ms = map.created_unix_ms;
  query_.limit = page_trees;
  query_.box = std::move(box);
}

std::vector<storage::TreeRecord> TreePages::Next() {
  std::vector<storage::TreeRecord> page;
  try {
    page = store_.ReadTreesPage(map_name_, query_);
  } catch (const storage::StorageError& e) {
    // After the first page, a missing map or version was deleted or pruned meanwhile.
    if (!query_.after_id || e.code() != storage::StorageError::Code::kNotFound) throw;
    throw ServiceError(ErrorCode::kAborted,
                       "map \"" + map_name_ + "\" (version " + std::to_string(query_.version) +
                           ") was deleted or pruned during the export (" + e.what() + "); retry");
  }
  done_ = static_cast<int64_t>(page.size()) < query_.limit;
  if (!page.empty()) query_.after_id = page.back().id;
  return page;
}

}  // namespace forestmap::server
