// Row-level helpers of SqliteMapStore: maps, trees (with their spatial index blocks),
// observations and history entries.

#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>

#include "storage/attribute_json.h"
#include "storage/sqlite/internal.h"
#include "storage/store_steps.h"

namespace forestmap::storage::internal {
namespace {

using sqlite::Database;
using sqlite::Statement;
using Code = StorageError::Code;

// Sort-Tile-Recursive packing (Leutenegger, Lopez, Edgington 1997, "STR: A simple and efficient
// algorithm for R-tree packing"): an order of the batch in which consecutive runs of
// kTreesPerBlock trees are compact tiles. Ranks only, so outliers do not spoil it.
std::vector<size_t> PackingOrder(const std::vector<TreeRecord>& trees) {
  constexpr size_t kBlock = SqliteMapStore::kTreesPerBlock;
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

// Inserts trees[index] through `insert` (map id at parameter 1, valid_from at 8, valid_to at
// 13). A staged row (pending_base >= 0) has its duplicate id reported as StagedDuplicate (the
// caller names both trees); a pending one (`pending`) also keeps its index in the
// upload, pending_base + index, in valid_from.
void InsertTree(Statement& insert, const std::string& map_name,
                const std::vector<TreeRecord>& trees, size_t index, int64_t id,
                int64_t pending_base, bool pending) {
  const TreeRecord& tree = trees[index];
  std::optional<std::string> attributes;
  try {
    attributes = EncodeAttributes(tree.attributes, tree.null_attributes);
  } catch (const nlohmann::json::exception& e) {
    throw StorageError(Code::kInvalidArgument, "map '" + map_name +
                                                   "': " + TreeLabel(trees, index) +
                                                   ": attributes are not valid UTF-8: " + e.what());
  }
  insert.BindInt64(2, id);
  insert.BindDouble(3, tree.x);
  insert.BindDouble(4, tree.y);
  insert.BindOptionalDouble(5, tree.z);
  insert.BindOptionalDouble(6, tree.dbh);
  if (attributes) {
    insert.BindText(7, *attributes);
  } else {
    insert.BindNull(7);
  }
  insert.BindInt64(9, tree.status == TreeStatus::kConfirmed ? 1 : 0);
  insert.BindInt64(10, tree.observations);
  insert.BindOptionalDouble(11, tree.position_sigma);
  insert.BindOptionalDouble(12, tree.dbh_sigma);
  if (pending) insert.BindInt64(8, pending_base + static_cast<int64_t>(index));
  try {
    insert.Run();
  } catch (const StorageError& e) {
    // Batches have no duplicates (checked before), so a UNIQUE violation is an id of the map.
    if (e.code() != Code::kAlreadyExists) throw;
    if (pending_base >= 0) throw StagedDuplicate{index};
    throw StorageError(Code::kInvalidArgument, "map '" + map_name +
                                                   "': " + TreeLabel(trees, index) +
                                                   ": tree id already exists in the map");
  }
}

}  // namespace

MapRow ReadMapRow(const Statement& row) {
  MapRow map;
  map.id = row.ColumnInt64(0);
  map.info.name = row.ColumnText(1);
  map.info.description = row.ColumnText(2);
  map.info.crs = row.ColumnText(3);
  map.info.version = row.ColumnInt64(4);
  map.info.tree_count = row.ColumnInt64(5);
  if (!row.ColumnIsNull(6)) {
    map.info.extent =
        Extent{row.ColumnDouble(6), row.ColumnDouble(7), row.ColumnDouble(8), row.ColumnDouble(9)};
  }
  map.info.created_unix_ms = row.ColumnInt64(10);
  map.info.updated_unix_ms = row.ColumnInt64(11);
  map.info.confirmed_count = row.ColumnInt64(12);
  return map;
}

MapRow RequireMap(Database& db, const std::string& name) {
  // A map that an upload is still creating (creating_upload set) does not exist yet.
  Statement select(
      db, "SELECT " FORESTMAP_MAP_COLUMNS " FROM maps WHERE name = ?1 AND creating_upload IS NULL");
  select.BindText(1, name);
  if (!select.Step()) {
    throw StorageError(Code::kNotFound, "map '" + name + "' does not exist");
  }
  return ReadMapRow(select);
}

void UpdateMapRow(Database& db, const MapRow& map) {
  const MapInfo& info = map.info;
  Statement update(db,
                   "UPDATE maps SET version = ?2, tree_count = ?3, min_x = ?4, min_y = ?5, "
                   "max_x = ?6, max_y = ?7, updated_unix_ms = ?8, confirmed_count = ?9 "
                   "WHERE id = ?1");
  update.BindInt64(1, map.id);
  update.BindInt64(2, info.version);
  update.BindInt64(3, info.tree_count);
  const auto bound = [&](double Extent::*field) -> std::optional<double> {
    if (!info.extent) return std::nullopt;
    return (*info.extent).*field;
  };
  update.BindOptionalDouble(4, bound(&Extent::min_x));
  update.BindOptionalDouble(5, bound(&Extent::min_y));
  update.BindOptionalDouble(6, bound(&Extent::max_x));
  update.BindOptionalDouble(7, bound(&Extent::max_y));
  update.BindInt64(8, info.updated_unix_ms);
  update.BindInt64(9, info.confirmed_count);
  update.Run();
}

std::optional<Extent> ScanExtent(Database& db, int64_t map_id) {
  Statement scan(db,
                 "SELECT MIN(x), MIN(y), MAX(x), MAX(y) FROM trees INDEXED BY trees_current "
                 "WHERE map_id = ?1 AND valid_to = " FORESTMAP_CURRENT);
  scan.BindInt64(1, map_id);
  if (!scan.Step() || scan.ColumnIsNull(0)) return std::nullopt;
  return Extent{scan.ColumnDouble(0), scan.ColumnDouble(1), scan.ColumnDouble(2),
                scan.ColumnDouble(3)};
}

TreeRecord ReadTreeRow(const Statement& row, const std::string& map_name) {
  TreeRecord tree;
  tree.id = row.ColumnInt64(0);
  tree.x = row.ColumnDouble(1);
  tree.y = row.ColumnDouble(2);
  tree.z = row.ColumnOptionalDouble(3);
  tree.dbh = row.ColumnOptionalDouble(4);
  if (!row.ColumnIsNull(5)) SetStoredAttributes(tree, row.ColumnText(5), map_name);
  tree.status = row.ColumnInt64(6) == 0 ? TreeStatus::kCandidate : TreeStatus::kConfirmed;
  tree.observations = row.ColumnInt64(7);
  tree.position_sigma = row.ColumnOptionalDouble(8);
  tree.dbh_sigma = row.ColumnOptionalDouble(9);
  return tree;
}

std::vector<size_t> InsertTrees(Database& db, const MapRow& map,
                                const std::vector<TreeRecord>& trees,
                                const std::vector<int64_t>& ids, int64_t valid_from,
                                int64_t valid_to, int64_t pending_base) {
  std::vector<size_t> order = PackingOrder(trees);
  const bool pending = pending_base >= 0 && valid_to < 0;
  Statement insert_tree(db,
                        "INSERT INTO trees (map_id, tree_id, x, y, z, dbh, attributes, valid_from, "
                        "valid_to, status, observations, position_sigma, dbh_sigma) VALUES (?1, "
                        "?2, ?3, ?4, ?5, ?6, ?7, ?8, ?13, ?9, ?10, ?11, ?12)");
  Statement insert_block(db,
                         "INSERT INTO tree_blocks (min_map, max_map, min_x, max_x, min_y, max_y, "
                         "map_id, first_rowid, last_rowid) VALUES (?1, ?1, ?2, ?3, ?4, ?5, ?1, "
                         "?6, ?7)");
  insert_tree.BindInt64(1, map.id);
  insert_tree.BindInt64(8, valid_from);
  insert_tree.BindInt64(13, valid_to);
  insert_block.BindInt64(1, map.id);
  // Beyond the float range the R*Tree would round the inner bound to infinity and lose the point.
  constexpr double kFloatSafe = 3e38;
  for (size_t begin = 0; begin < order.size(); begin += SqliteMapStore::kTreesPerBlock) {
    const size_t end = std::min(order.size(), begin + SqliteMapStore::kTreesPerBlock);
    std::optional<Extent> box;
    int64_t first_rowid = std::numeric_limits<int64_t>::max();
    int64_t last_rowid = std::numeric_limits<int64_t>::min();
    for (size_t k = begin; k < end; ++k) {
      const size_t i = order[k];
      InsertTree(insert_tree, map.info.name, trees, i, ids[i], pending_base, pending);
      first_rowid = std::min(first_rowid, db.LastInsertRowId());
      last_rowid = std::max(last_rowid, db.LastInsertRowId());
      box = Union(box, Extent{trees[i].x, trees[i].y, trees[i].x, trees[i].y});
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

ObservationRecord ReadObservationRow(const Statement& row) {
  ObservationRecord o;
  o.id = row.ColumnInt64(0);
  o.tree_id = row.ColumnInt64(1);
  o.source = row.ColumnText(2);
  o.frame_id = row.ColumnInt64(3);
  o.detection_index = static_cast<int32_t>(row.ColumnInt64(4));
  o.x = row.ColumnDouble(5);
  o.y = row.ColumnDouble(6);
  o.z = row.ColumnOptionalDouble(7);
  o.dbh = row.ColumnOptionalDouble(8);
  o.weight_xy = row.ColumnDouble(9);
  o.weight_dbh = row.ColumnDouble(10);
  o.sensor_x = row.ColumnDouble(11);
  o.sensor_y = row.ColumnDouble(12);
  o.sensor_z = row.ColumnDouble(13);
  o.prior = row.ColumnInt64(14) != 0;
  o.version = row.ColumnInt64(15);
  return o;
}

void InsertObservations(Database& db, int64_t map_id,
                        const std::vector<ObservationRecord>& observations, int64_t valid_from) {
  Statement insert(
      db,
      "INSERT INTO observations (map_id, tree_id, valid_from, valid_to, source, "
      "frame_id, detection_index, x, y, z, dbh, weight_xy, weight_dbh, sensor_x, "
      "sensor_y, sensor_z, prior, cell_x, cell_y) VALUES (?1, ?2, ?3, " FORESTMAP_CURRENT
      ", ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, "
      "?17, ?18)");
  insert.BindInt64(1, map_id);
  insert.BindInt64(3, valid_from);
  for (const ObservationRecord& o : observations) {
    insert.BindInt64(2, o.tree_id);
    insert.BindText(4, o.source);
    insert.BindInt64(5, o.frame_id);
    insert.BindInt64(6, o.detection_index);
    insert.BindDouble(7, o.x);
    insert.BindDouble(8, o.y);
    insert.BindOptionalDouble(9, o.z);
    insert.BindOptionalDouble(10, o.dbh);
    insert.BindDouble(11, o.weight_xy);
    insert.BindDouble(12, o.weight_dbh);
    insert.BindDouble(13, o.sensor_x);
    insert.BindDouble(14, o.sensor_y);
    insert.BindDouble(15, o.sensor_z);
    insert.BindInt64(16, o.prior ? 1 : 0);
    const ObservationCell cell = CellOf(o.x, o.y);
    insert.BindInt64(17, cell.x);
    insert.BindInt64(18, cell.y);
    insert.Run();
  }
}

void InsertVersion(Database& db, int64_t map_id, const VersionRecord& r) {
  Statement insert(db,
                   "INSERT INTO map_versions (map_id, version, created_unix_ms, kind, source, "
                   "tree_count, confirmed_count, trees_added, trees_updated, trees_removed, "
                   "observations_added, observations_removed, restored_from) VALUES (?1, ?2, "
                   "?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13)");
  insert.BindInt64(1, map_id);
  insert.BindInt64(2, r.version);
  insert.BindInt64(3, r.created_unix_ms);
  insert.BindInt64(4, static_cast<int64_t>(r.kind));
  insert.BindText(5, r.source);
  insert.BindInt64(6, r.tree_count);
  insert.BindInt64(7, r.confirmed_count);
  insert.BindInt64(8, r.trees_added);
  insert.BindInt64(9, r.trees_updated);
  insert.BindInt64(10, r.trees_removed);
  insert.BindInt64(11, r.observations_added);
  insert.BindInt64(12, r.observations_removed);
  insert.BindInt64(13, r.restored_from);
  insert.Run();
}

}  // namespace forestmap::storage::internal
