// The SQLite session's tree rows: inserted block by block with their R*Tree rows (the spatial
// index holds blocks of up to kTreesPerBlock nearby trees, see storage/sqlite/store.h), read
// through the partial indexes of current and closed rows, closed by later versions.

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "storage/sqlite/internal.h"

namespace forestmap::storage::sqlite {
namespace {

using Code = StorageError::Code;
constexpr size_t kBlock = SqliteMapStore::kTreesPerBlock;

// Sort-Tile-Recursive packing (Leutenegger, Lopez, Edgington 1997, "STR: A simple and efficient
// algorithm for R-tree packing"): an order of the batch in which consecutive runs of kBlock
// trees are compact tiles. Ranks only, so outliers do not spoil it.
std::vector<size_t> PackingOrder(const std::vector<TreeRecord>& trees) {
  // Sort compact (coordinate, index) keys: comparing through the records would miss the cache.
  std::vector<std::pair<double, size_t>> keys(trees.size());
  for (size_t i = 0; i < trees.size(); ++i) keys[i] = {trees[i].x, i};
  std::sort(keys.begin(), keys.end());
  const size_t blocks = (trees.size() + kBlock - 1) / kBlock;
  const auto slices = static_cast<size_t>(std::ceil(std::sqrt(static_cast<double>(blocks))));
  const size_t slice_size = std::max<size_t>(slices, 1) * kBlock;
  for (size_t begin = 0; begin < keys.size(); begin += slice_size) {
    const size_t end = std::min(keys.size(), begin + slice_size);
    for (size_t k = begin; k < end; ++k) keys[k].first = trees[keys[k].second].y;
    std::sort(keys.begin() + static_cast<std::ptrdiff_t>(begin),
              keys.begin() + static_cast<std::ptrdiff_t>(end));
  }
  std::vector<size_t> order(keys.size());
  for (size_t k = 0; k < keys.size(); ++k) order[k] = keys[k].second;
  return order;
}

// Inserts trees[index] through `insert` (map id ?1, valid_from ?2, valid_to ?3, the values of
// WriteTreeValues from ?4). A staged row (pending_base >= 0) has its duplicate id reported as
// StagedDuplicate (the caller names both trees); a pending one (`pending`) also keeps its index
// in the upload, pending_base + index, in valid_from.
void InsertTree(Statement& insert, const std::string& map_name,
                const std::vector<TreeRecord>& trees, size_t index, int64_t id,
                int64_t pending_base, bool pending) {
  Binder values(insert, 4);
  internal::WriteTreeValues(values, id, trees[index],
                            internal::StoredAttributes(map_name, trees, index));
  if (pending) insert.BindInt64(2, pending_base + static_cast<int64_t>(index));
  try {
    insert.Run();
  } catch (const StorageError& e) {
    // Batches have no duplicates (checked before), so a UNIQUE violation is an id of the map.
    if (e.code() != Code::kAlreadyExists) throw;
    if (pending_base >= 0) throw StagedDuplicate{index};
    throw StorageError(Code::kInvalidArgument, "map '" + map_name +
                                                   "': " + internal::TreeLabel(trees, index) +
                                                   ": tree id already exists in the map");
  }
}

// Every tree row of `select`, read as trees of `map`.
std::vector<TreeRecord> ReadTrees(Statement& select, const MapRow& map) {
  return ReadAll(select, [&](const Row& row) { return internal::ReadTreeRow(row, map.info.name); });
}

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

}  // namespace

std::vector<size_t> InsertTrees(Database& db, const MapRow& map,
                                const std::vector<TreeRecord>& trees,
                                const std::vector<int64_t>& ids, int64_t valid_from,
                                int64_t valid_to, int64_t pending_base) {
  std::vector<size_t> order = PackingOrder(trees);
  const bool pending = pending_base >= 0 && valid_to < 0;
  Statement insert_tree(db,
                        "INSERT INTO trees (map_id, valid_from, valid_to, tree_id, x, y, z, dbh, "
                        "attributes, status, observations, position_sigma, dbh_sigma, "
                        "last_seen_unix_ms, evidence) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, "
                        "?9, ?10, ?11, ?12, ?13, ?14, ?15)");
  Statement insert_block(db,
                         "INSERT INTO tree_blocks (min_map, max_map, min_x, max_x, min_y, max_y, "
                         "map_id, first_rowid, last_rowid) VALUES (?1, ?1, ?2, ?3, ?4, ?5, ?1, "
                         "?6, ?7)");
  insert_tree.BindInt64(1, map.id);
  insert_tree.BindInt64(2, valid_from);
  insert_tree.BindInt64(3, valid_to);
  insert_block.BindInt64(1, map.id);
  // Beyond the float range the R*Tree would round the inner bound to infinity and lose the point.
  constexpr double kFloatSafe = 3e38;
  for (size_t begin = 0; begin < order.size(); begin += kBlock) {
    const size_t end = std::min(order.size(), begin + kBlock);
    std::optional<Extent> box;
    int64_t first_rowid = std::numeric_limits<int64_t>::max();
    int64_t last_rowid = std::numeric_limits<int64_t>::min();
    for (size_t k = begin; k < end; ++k) {
      const size_t i = order[k];
      InsertTree(insert_tree, map.info.name, trees, i, ids[i], pending_base, pending);
      first_rowid = std::min(first_rowid, db.LastInsertRowId());
      last_rowid = std::max(last_rowid, db.LastInsertRowId());
      box = internal::Union(box, Extent{trees[i].x, trees[i].y, trees[i].x, trees[i].y});
    }
    insert_block.BindDouble(2, std::min(box->min_x, kFloatSafe));
    insert_block.BindDouble(3, std::max(box->max_x, -kFloatSafe));
    insert_block.BindDouble(4, std::min(box->min_y, kFloatSafe));
    insert_block.BindDouble(5, std::max(box->max_y, -kFloatSafe));
    insert_block.BindInt64(6, first_rowid);
    insert_block.BindInt64(7, last_rowid);
    insert_block.Run();
  }
  return order;
}

// ---- Trees ----

std::vector<TreeRecord> Session::CurrentTrees(const MapRow& map) {
  Statement select(db_,
                   "SELECT " FORESTMAP_TREE_COLUMNS
                   " FROM trees AS t INDEXED BY trees_current WHERE t.map_id = ?1 AND "
                   "t.valid_to = " FORESTMAP_CURRENT " ORDER BY t.tree_id",
                   map.id);
  std::vector<TreeRecord> trees;
  trees.reserve(static_cast<size_t>(map.info.tree_count));
  while (select.Step()) trees.push_back(internal::ReadTreeRow(Row(select), map.info.name));
  return trees;
}

std::vector<TreeRecord> Session::TreesAtVersion(const MapRow& map, int64_t version) {
  Statement select(db_,
                   "SELECT " FORESTMAP_TREE_COLUMNS
                   " FROM trees AS t INDEXED BY trees_current "
                   "WHERE t.map_id = ?1 AND t.valid_to = " FORESTMAP_CURRENT
                   " AND t.valid_from <= ?2 UNION ALL SELECT " FORESTMAP_TREE_COLUMNS
                   " FROM trees AS t INDEXED BY trees_history WHERE t.map_id = ?1 AND "
                   "t.valid_to != " FORESTMAP_CURRENT
                   " AND t.valid_from <= ?2 AND t.valid_to > ?2 ORDER BY 1",
                   map.id, version);
  return ReadTrees(select, map);
}

std::vector<TreeRecord> Session::TreesInBox(const MapRow& map, const Extent& box) {
  // CROSS JOIN keeps the R*Tree as the outer loop: blocks near the box, then each block's rowid
  // range. The conditions on t filter the float32 superset exactly and drop rows of older
  // versions; the unary + keeps SQLite from walking all trees of the map by an index on map_id
  // instead of the range.
  Statement select(db_,
                   "SELECT " FORESTMAP_TREE_COLUMNS
                   " FROM tree_blocks AS b "
                   "CROSS JOIN trees AS t ON t.rowid BETWEEN b.first_rowid AND b.last_rowid "
                   "WHERE b.min_map <= ?1 AND b.max_map >= ?1 AND b.min_x <= ?3 AND "
                   "b.max_x >= ?2 AND b.min_y <= ?5 AND b.max_y >= ?4 AND b.map_id = ?1 AND "
                   "+t.map_id = ?1 AND +t.valid_to = " FORESTMAP_CURRENT
                   " AND t.x >= ?2 AND t.x <= ?3 AND t.y >= ?4 AND t.y <= ?5 "
                   "ORDER BY t.tree_id",
                   map.id, box.min_x, box.max_x, box.min_y, box.max_y);
  std::vector<TreeRecord> trees;
  while (select.Step()) {
    // Blocks never share rows, but should rowids ever be reused out of order (SQLite does so
    // only after rowid 2^63 - 1), a row could sit in two ranges: keep it once.
    TreeRecord tree = internal::ReadTreeRow(Row(select), map.info.name);
    if (trees.empty() || trees.back().id != tree.id) trees.push_back(std::move(tree));
  }
  return trees;
}

std::vector<TreeRecord> Session::TreesById(const MapRow& map, std::span<const int64_t> ids) {
  Statement select(db_,
                   "SELECT " FORESTMAP_TREE_COLUMNS
                   " FROM trees AS t INDEXED BY trees_current "
                   "WHERE t.map_id = ?1 AND t.tree_id = ?2 AND t.valid_to = " FORESTMAP_CURRENT,
                   map.id);
  std::vector<TreeRecord> trees;
  for (const int64_t id : std::set<int64_t>(ids.begin(), ids.end())) {
    select.BindInt64(2, id);
    if (select.Step()) trees.push_back(internal::ReadTreeRow(Row(select), map.info.name));
    select.Reset();
  }
  return trees;
}

// Each query walks its index in id order and stops after `limit` matches.
std::vector<TreeRecord> Session::CurrentPage(const MapRow& map, const TreePageQuery& query) {
  Statement select(db_, "SELECT " FORESTMAP_TREE_COLUMNS
                        " FROM trees AS t INDEXED BY trees_current WHERE t.map_id = ?1 AND "
                        "t.valid_to = " FORESTMAP_CURRENT
                        " AND t.valid_from <= ?2 AND t.tree_id > ?3 AND t.x >= ?5 AND "
                        "t.x <= ?6 AND t.y >= ?7 AND t.y <= ?8 ORDER BY t.tree_id LIMIT ?4");
  BindPage(select, map.id, query);
  return ReadTrees(select, map);
}

std::vector<TreeRecord> Session::ClosedPage(const MapRow& map, const TreePageQuery& query) {
  Statement select(db_, "SELECT " FORESTMAP_TREE_COLUMNS
                        " FROM trees AS t INDEXED BY trees_history WHERE t.map_id = ?1 AND "
                        "t.valid_to != " FORESTMAP_CURRENT
                        " AND t.valid_from <= ?2 AND t.valid_to > ?2 AND t.tree_id > ?3 AND "
                        "t.x >= ?5 AND t.x <= ?6 AND t.y >= ?7 AND t.y <= ?8 ORDER BY t.tree_id "
                        "LIMIT ?4");
  BindPage(select, map.id, query);
  return ReadTrees(select, map);
}

std::optional<int64_t> Session::MaxCurrentTreeId(int64_t map_id) {
  return Statement(db_,
                   "SELECT MAX(tree_id) FROM trees INDEXED BY trees_current WHERE map_id = ?1 "
                   "AND valid_to = " FORESTMAP_CURRENT,
                   map_id)
      .OptionalInt64();
}

std::optional<int64_t> Session::MaxTreeIdEver(int64_t map_id) {
  // Both partial indexes answer MAX directly; together they cover every row.
  Statement select(db_,
                   "SELECT MAX(m) FROM (SELECT MAX(tree_id) AS m FROM trees INDEXED BY "
                   "trees_current WHERE map_id = ?1 AND valid_to = " FORESTMAP_CURRENT
                   " UNION ALL SELECT MAX(tree_id) FROM trees INDEXED BY trees_history WHERE "
                   "map_id = ?1 AND valid_to != " FORESTMAP_CURRENT ")",
                   map_id);
  return select.OptionalInt64();
}

void Session::InsertTrees(const MapRow& map, const std::vector<TreeRecord>& trees,
                          const std::vector<int64_t>& ids, int64_t valid_from) {
  sqlite::InsertTrees(db_, map, trees, ids, valid_from);
}

std::vector<ClosedTree> Session::CloseTrees(int64_t map_id, std::span<const int64_t> ids,
                                            int64_t version) {
  Statement close(db_,
                  "UPDATE trees SET valid_to = ?2 WHERE map_id = ?1 AND tree_id = ?3 AND "
                  "valid_to = " FORESTMAP_CURRENT " RETURNING status, x, y",
                  map_id, version);
  std::vector<ClosedTree> closed;
  for (const int64_t id : ids) {
    close.BindInt64(3, id);
    if (close.Step()) {
      closed.push_back(
          {id, close.ColumnInt64(0) != 0, close.ColumnDouble(1), close.ColumnDouble(2)});
    }
    close.Reset();
  }
  return closed;
}

int64_t Session::CloseAllRows(int64_t map_id, int64_t version) {
  Statement(db_,
            "UPDATE trees SET valid_to = ?2 WHERE map_id = ?1 AND valid_to = " FORESTMAP_CURRENT,
            map_id, version)
      .Run();
  Statement(
      db_,
      "UPDATE observations SET valid_to = ?2 WHERE map_id = ?1 AND valid_to = " FORESTMAP_CURRENT,
      map_id, version)
      .Run();
  return db_.Changes();
}

std::vector<TreeRecord> Session::ClosedTreesAt(const MapRow& map, int64_t version) {
  Statement select(db_,
                   "SELECT " FORESTMAP_TREE_COLUMNS
                   " FROM trees AS t INDEXED BY trees_history WHERE t.map_id = ?1 AND "
                   "t.valid_to != " FORESTMAP_CURRENT " AND t.valid_from <= ?2 AND t.valid_to > ?2",
                   map.id, version);
  return ReadTrees(select, map);
}

std::vector<int64_t> Session::CloseTreesAddedAfter(int64_t map_id, int64_t version, int64_t at) {
  Statement close(db_,
                  "UPDATE trees SET valid_to = ?3 WHERE map_id = ?1 AND valid_from > ?2 AND "
                  "valid_to = " FORESTMAP_CURRENT " RETURNING tree_id",
                  map_id, version, at);
  return ReadAll(close, [](const Row& row) { return row.Int64(0); });
}

}  // namespace forestmap::storage::sqlite
