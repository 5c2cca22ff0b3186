// SqliteMapStore::ReadTreesPage: exports read page by page (storage/staged_writes.h).

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "storage/sqlite.h"
#include "storage/sqlite_map_store.h"
#include "storage/sqlite_map_store_internal.h"
#include "storage/staged_writes.h"

namespace forestmap::storage {
namespace {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;
using Code = StorageError::Code;
using internal::MapRow;

constexpr double kInf = std::numeric_limits<double>::infinity();

// Binds ?1 map id, ?2 version, ?3 after id, ?4 limit, ?5..?8 the box (infinite without one).
void BindPage(Statement& select, int64_t map_id, const TreePageQuery& query) {
  select.BindInt64(1, map_id);
  select.BindInt64(2, query.version);
  select.BindInt64(3, query.after_id.value_or(std::numeric_limits<int64_t>::min()));
  select.BindInt64(4, query.limit);
  select.BindDouble(5, query.box ? query.box->min_x : -kInf);
  select.BindDouble(6, query.box ? query.box->max_x : kInf);
  select.BindDouble(7, query.box ? query.box->min_y : -kInf);
  select.BindDouble(8, query.box ? query.box->max_y : kInf);
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
  std::sort(trees.begin(), trees.end(),
            [](const TreeRecord& a, const TreeRecord& b) { return *a.id < *b.id; });
  if (static_cast<int64_t>(trees.size()) > query.limit) {
    trees.resize(static_cast<size_t>(query.limit));
  }
  return trees;
}

}  // namespace

std::vector<TreeRecord> SqliteMapStore::ReadTreesPage(const std::string& name,
                                                      const TreePageQuery& query) {
  internal::CheckName(name);
  if (query.version < 1 || query.limit < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': a page needs version >= 1 " + "and limit >= 1");
  }
  if (query.box) internal::CheckBox(name, *query.box);
  std::vector<TreeRecord> trees;
  WithReader([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kRead);  // the page and its checks agree
    const MapRow map = internal::RequireMap(db, name);
    if (query.created_unix_ms != 0 && map.info.created_unix_ms != query.created_unix_ms) {
      throw StorageError(Code::kConflict, "map '" + name +
                                              "' was deleted and created again during the "
                                              "export; retry");
    }
    if (query.version > map.info.version) {
      throw StorageError(Code::kNotFound, "map '" + name + "' has no version " +
                                              std::to_string(query.version) + " yet");
    }
    // kNotFound once the version is pruned: its rows may be gone.
    if (query.version != map.info.version) internal::RequireVersion(db, map, query.version);
    trees = PageRows(db, map, query);
    transaction.Commit();
  });
  return trees;
}

}  // namespace forestmap::storage
