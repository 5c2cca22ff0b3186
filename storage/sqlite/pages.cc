// SqliteMapStore::ReadTreesPage: exports read page by page (storage/staged_writes.h).

#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"
#include "storage/sqlite/store.h"
#include "storage/staged_writes.h"
#include "storage/store_steps.h"

namespace forestmap::storage {
namespace {

using internal::MapRow;
using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;

// Binds ?1 map id, ?2 version, ?3 after id, ?4 limit, ?5..?8 the box (infinite without one).
void BindPage(Statement& select, int64_t map_id, const TreePageQuery& query) {
  const Extent box = internal::PageBox(query);
  select.BindInt64(1, map_id);
  select.BindInt64(2, query.version);
  select.BindInt64(3, internal::PageAfterId(query));
  select.BindInt64(4, query.limit);
  select.BindDouble(5, box.min_x);
  select.BindDouble(6, box.max_x);
  select.BindDouble(7, box.min_y);
  select.BindDouble(8, box.max_y);
}

// Rows of the version that are still current, then (for an older version) closed rows that were
// valid then: each query walks its index in id order and stops after `limit` matches.
std::vector<TreeRecord> PageRows(Database& db, const MapRow& map, const TreePageQuery& query) {
  std::vector<TreeRecord> trees;
  Statement current(db, "SELECT " FORESTMAP_TREE_COLUMNS
                        " FROM trees AS t INDEXED BY trees_current WHERE t.map_id = ?1 AND "
                        "t.valid_to = " FORESTMAP_CURRENT
                        " AND t.valid_from <= ?2 AND t.tree_id > ?3 AND t.x >= ?5 AND "
                        "t.x <= ?6 AND t.y >= ?7 AND t.y <= ?8 ORDER BY t.tree_id LIMIT ?4");
  BindPage(current, map.id, query);
  while (current.Step()) trees.push_back(internal::ReadTreeRow(current, map.info.name));
  if (query.version == map.info.version) return trees;
  Statement closed(db, "SELECT " FORESTMAP_TREE_COLUMNS
                       " FROM trees AS t INDEXED BY trees_history WHERE t.map_id = ?1 AND "
                       "t.valid_to != " FORESTMAP_CURRENT
                       " AND t.valid_from <= ?2 AND t.valid_to > ?2 AND t.tree_id > ?3 AND "
                       "t.x >= ?5 AND t.x <= ?6 AND t.y >= ?7 AND t.y <= ?8 ORDER BY t.tree_id "
                       "LIMIT ?4");
  BindPage(closed, map.id, query);
  while (closed.Step()) trees.push_back(internal::ReadTreeRow(closed, map.info.name));
  internal::SortAndTrimPage(trees, query.limit);
  return trees;
}

}  // namespace

std::vector<TreeRecord> SqliteMapStore::ReadTreesPage(const std::string& name,
                                                      const TreePageQuery& query) {
  internal::CheckName(name);
  internal::CheckPageQuery(name, query);
  std::vector<TreeRecord> trees;
  WithReader([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kRead);  // the page and its checks agree
    const MapRow map = internal::RequireMap(db, name);
    internal::CheckPageTarget(name, query, map.info);
    // kNotFound once the version is pruned: its rows may be gone.
    if (query.version != map.info.version) internal::RequireVersion(db, map, query.version);
    trees = PageRows(db, map, query);
    transaction.Commit();
  });
  return trees;
}

}  // namespace forestmap::storage
