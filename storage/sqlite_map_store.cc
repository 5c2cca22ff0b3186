#include "storage/sqlite_map_store.h"

#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>

#include "storage/sqlite.h"

namespace forestmap::storage {
namespace {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;
using Code = StorageError::Code;

// ---- Schema ----

// Step i takes a database from user_version i to i + 1 (see sqlite::MigrateSchema). Never edit a
// shipped step: append a new one and bump kSchemaVersion.
//
// tree_blocks is the spatial index: one R*Tree row per block of trees of one map that were
// written together and lie close together; the block's trees occupy the rowids first_rowid ..
// last_rowid of `trees`. map_id is an index dimension so a box query on one map does not wade
// through other maps in the same frame, and an auxiliary column for exact matching (the R*Tree
// keeps 32-bit floats, rounded outwards: it answers a superset that queries filter exactly).
// ON DELETE CASCADE does not reach a virtual table: whoever deletes trees deletes their blocks.
const std::vector<const char*> kSchemaSteps = {
    R"sql(
CREATE TABLE maps (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  description TEXT NOT NULL,
  crs TEXT NOT NULL,
  version INTEGER NOT NULL,
  tree_count INTEGER NOT NULL,
  min_x REAL, min_y REAL, max_x REAL, max_y REAL,  -- NULL for an empty map
  created_unix_ms INTEGER NOT NULL,
  updated_unix_ms INTEGER NOT NULL
);
CREATE TABLE trees (
  rowid INTEGER PRIMARY KEY,
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  tree_id INTEGER NOT NULL,
  x REAL NOT NULL,
  y REAL NOT NULL,
  z REAL,
  dbh REAL,
  attributes TEXT,  -- JSON object of strings, NULL when there are none
  UNIQUE (map_id, tree_id)
);
CREATE VIRTUAL TABLE tree_blocks USING rtree(
  id, min_map, max_map, min_x, max_x, min_y, max_y, +map_id, +first_rowid, +last_rowid);
PRAGMA user_version = 1;
)sql",
};

void ConfigureConnection(Database& db, const SqliteMapStoreOptions& options, bool read_only) {
  // synchronous = NORMAL is durable against application crashes in WAL mode; a power loss may
  // only drop the last commits, never corrupt the file.
  db.Execute("PRAGMA foreign_keys = ON; PRAGMA synchronous = NORMAL");
  // PRAGMA values cannot be bound; this one is an integer from checked options, not user text.
  // A negative cache_size is in KiB.
  const std::string cache_sql = "PRAGMA cache_size = -" + std::to_string(options.cache_mib * 1024);
  db.Execute(cache_sql.c_str());
  if (read_only) db.Execute("PRAGMA query_only = ON");
}

// ---- Rows ----

int64_t NowUnixMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void CheckName(const std::string& name) {
  const std::string problem = ValidateMapName(name);
  if (problem.empty()) return;
  constexpr size_t kShownChars = 64;
  const std::string shown = name.size() > kShownChars ? name.substr(0, kShownChars) + "..." : name;
  throw StorageError(Code::kInvalidArgument, "invalid map name '" + shown + "': " + problem);
}

struct MapRow {
  int64_t id = 0;
  MapInfo info;
};

// Columns of every maps query, in the order ReadMapRow expects.
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
  return map;
}

MapRow RequireMap(Database& db, const std::string& name) {
  Statement select(db,
                   "SELECT id, name, description, crs, version, tree_count, min_x, min_y, max_x, "
                   "max_y, created_unix_ms, updated_unix_ms FROM maps WHERE name = ?1");
  select.BindText(1, name);
  if (!select.Step()) {
    throw StorageError(Code::kNotFound, "map '" + name + "' does not exist");
  }
  return ReadMapRow(select);
}

std::optional<std::string> EncodeAttributes(const std::map<std::string, std::string>& attributes) {
  if (attributes.empty()) return std::nullopt;
  return nlohmann::json(attributes).dump();  // throws json::type_error on invalid UTF-8
}

// Columns: tree_id, x, y, z, dbh, attributes.
TreeRecord ReadTreeRow(const Statement& row, const std::string& map_name) {
  TreeRecord tree;
  tree.id = row.ColumnInt64(0);
  tree.x = row.ColumnDouble(1);
  tree.y = row.ColumnDouble(2);
  tree.z = row.ColumnOptionalDouble(3);
  tree.dbh = row.ColumnOptionalDouble(4);
  if (!row.ColumnIsNull(5)) {
    try {
      tree.attributes =
          nlohmann::json::parse(row.ColumnText(5)).get<std::map<std::string, std::string>>();
    } catch (const nlohmann::json::exception& e) {
      throw StorageError(Code::kInternal, "map '" + map_name + "' tree " +
                                              std::to_string(*tree.id) +
                                              ": stored attributes are not a JSON object of "
                                              "strings: " +
                                              e.what());
    }
  }
  return tree;
}

// ---- Writing trees ----

// What a batch needs before it touches the database, checked up front.
struct BatchSummary {
  std::optional<int64_t> max_explicit_id;
  size_t auto_id_count = 0;
  std::optional<Extent> extent;
};

std::optional<Extent> Union(const std::optional<Extent>& a, const std::optional<Extent>& b) {
  if (!a) return b;
  if (!b) return a;
  return Extent{std::min(a->min_x, b->min_x), std::min(a->min_y, b->min_y),
                std::max(a->max_x, b->max_x), std::max(a->max_y, b->max_y)};
}

std::string TreeLabel(const std::vector<TreeRecord>& trees, size_t index) {
  std::string label = "tree at index " + std::to_string(index);
  if (trees[index].id) label += " (id " + std::to_string(*trees[index].id) + ")";
  return label;
}

BatchSummary CheckBatch(const std::string& map_name, const std::vector<TreeRecord>& trees) {
  BatchSummary summary;
  std::vector<std::pair<int64_t, size_t>> ids;  // (id, index in batch)
  for (size_t i = 0; i < trees.size(); ++i) {
    const TreeRecord& tree = trees[i];
    const auto reject = [&](const char* field, double value) {
      throw StorageError(Code::kInvalidArgument,
                         "map '" + map_name + "': " + TreeLabel(trees, i) + ": " + field +
                             " must be a finite number, got " + std::to_string(value));
    };
    if (!std::isfinite(tree.x)) reject("x", tree.x);
    if (!std::isfinite(tree.y)) reject("y", tree.y);
    if (tree.z && !std::isfinite(*tree.z)) reject("z", *tree.z);
    if (tree.dbh && !std::isfinite(*tree.dbh)) reject("dbh", *tree.dbh);
    summary.extent = Union(summary.extent, Extent{tree.x, tree.y, tree.x, tree.y});
    if (tree.id) {
      ids.emplace_back(*tree.id, i);
    } else {
      ++summary.auto_id_count;
    }
  }
  std::sort(ids.begin(), ids.end());
  for (size_t k = 1; k < ids.size(); ++k) {
    if (ids[k].first == ids[k - 1].first) {
      throw StorageError(Code::kInvalidArgument, "map '" + map_name + "': duplicate tree id " +
                                                     std::to_string(ids[k].first) + " at indices " +
                                                     std::to_string(ids[k - 1].second) + " and " +
                                                     std::to_string(ids[k].second) +
                                                     " of the batch");
    }
  }
  if (!ids.empty()) summary.max_explicit_id = ids.back().first;
  return summary;
}

// First id handed to the `count` trees without one: above `max_id` (the largest id they must not
// reuse), and at least 1. Unused (0) when count is 0.
int64_t FirstAutoId(const std::string& map_name, std::optional<int64_t> max_id, size_t count) {
  if (count == 0) return 0;
  const int64_t above = std::max<int64_t>(max_id.value_or(0), 0);
  constexpr int64_t kMax = std::numeric_limits<int64_t>::max();
  if (static_cast<uint64_t>(kMax - above) < count) {
    throw StorageError(Code::kInvalidArgument, "map '" + map_name +
                                                   "': no free tree ids left above " +
                                                   std::to_string(above) + " for " +
                                                   std::to_string(count) + " trees without an id");
  }
  return above + 1;
}

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

// Inserts trees[index] with `id` through `insert` (map id bound at parameter 1).
void InsertTree(Statement& insert, const std::string& map_name,
                const std::vector<TreeRecord>& trees, size_t index, int64_t id) {
  const TreeRecord& tree = trees[index];
  std::optional<std::string> attributes;
  try {
    attributes = EncodeAttributes(tree.attributes);
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
  try {
    insert.Run();
  } catch (const StorageError& e) {
    // The batch has no duplicates (CheckBatch), so a UNIQUE violation is an id of the map.
    if (e.code() != Code::kAlreadyExists) throw;
    throw StorageError(Code::kInvalidArgument, "map '" + map_name +
                                                   "': " + TreeLabel(trees, index) +
                                                   ": tree id already exists in the map");
  }
}

// Inserts the batch block by block: the trees of a block, then its index row.
void InsertTrees(Database& db, const MapRow& map, const std::vector<TreeRecord>& trees,
                 int64_t first_auto_id) {
  std::vector<int64_t> ids(trees.size());  // assigned in batch order, whatever the packing
  int64_t assigned = 0;  // counted apart so the last id may be INT64_MAX without overflow
  for (size_t i = 0; i < trees.size(); ++i) {
    ids[i] = trees[i].id ? *trees[i].id : first_auto_id + assigned++;
  }
  const std::vector<size_t> order = PackingOrder(trees);

  Statement insert_tree(db,
                        "INSERT INTO trees (map_id, tree_id, x, y, z, dbh, attributes) "
                        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)");
  Statement insert_block(db,
                         "INSERT INTO tree_blocks (min_map, max_map, min_x, max_x, min_y, max_y, "
                         "map_id, first_rowid, last_rowid) VALUES (?1, ?1, ?2, ?3, ?4, ?5, ?1, "
                         "?6, ?7)");
  insert_tree.BindInt64(1, map.id);
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
      InsertTree(insert_tree, map.info.name, trees, i, ids[i]);
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
}

void DeleteTreesOfMap(Database& db, int64_t map_id) {
  Statement blocks(db,
                   "DELETE FROM tree_blocks WHERE min_map <= ?1 AND max_map >= ?1 AND "
                   "map_id = ?1");
  blocks.BindInt64(1, map_id);
  blocks.Run();
  Statement trees(db, "DELETE FROM trees WHERE map_id = ?1");
  trees.BindInt64(1, map_id);
  trees.Run();
}

}  // namespace

void SqliteMapStoreOptions::Check() const {
  const auto fail = [](const std::string& message) {
    throw StorageError(Code::kInvalidArgument, "SqliteMapStoreOptions: " + message);
  };
  if (busy_timeout_ms < 0) fail("busy_timeout_ms must be >= 0");
  if (max_readers < 1) fail("max_readers must be >= 1");
  if (cache_mib < 1 || cache_mib > 1024 * 1024) fail("cache_mib must be in [1, 1048576]");
}

// ---- Connections ----

SqliteMapStore::SqliteMapStore(const std::string& path, const SqliteMapStoreOptions& options)
    : options_(options) {
  options_.Check();
  if (path.empty()) {
    throw StorageError(Code::kInvalidArgument, "database path is empty (use ':memory:')");
  }
  if (sqlite3_threadsafe() == 0) {
    throw StorageError(Code::kInternal, "the linked SQLite library was built without threads");
  }
  // NOMUTEX: each connection is used by one thread at a time (our mutex or the pool see to it).
  writer_ = std::make_unique<Database>(
      path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
      options_.busy_timeout_ms);
  ConfigureConnection(*writer_, options_, /*read_only=*/false);
  if (static_cast<int64_t>(kSchemaSteps.size()) != kSchemaVersion) {
    throw StorageError(StorageError::Code::kInternal, "schema steps and kSchemaVersion disagree");
  }
  sqlite::MigrateSchema(*writer_, kSchemaSteps);  // refuses a newer schema before any change
  if (path == ":memory:") return;                 // the database exists on this one connection only
  writer_->EnableWal();
  const SqliteMapStoreOptions reader_options = options_;
  readers_ = std::make_unique<sqlite::ConnectionPool>(
      [path, reader_options] {
        auto reader = std::make_unique<Database>(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX,
                                                 reader_options.busy_timeout_ms);
        ConfigureConnection(*reader, reader_options, /*read_only=*/true);
        return reader;
      },
      options_.max_readers);
}

SqliteMapStore::~SqliteMapStore() = default;

void SqliteMapStore::WithWriter(const Body& body) {
  std::lock_guard<std::mutex> lock(writer_mutex_);
  body(*writer_);
}

void SqliteMapStore::WithReader(const Body& body) {
  if (readers_) {
    readers_->With(body);
  } else {
    WithWriter(body);
  }
}

// ---- Maps ----

MapInfo SqliteMapStore::CreateMap(const std::string& name, const std::string& description,
                                  const std::string& crs) {
  CheckName(name);
  MapInfo info;
  info.name = name;
  info.description = description;
  info.crs = crs;
  info.version = 1;
  info.created_unix_ms = info.updated_unix_ms = NowUnixMs();
  WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    Statement insert(db,
                     "INSERT INTO maps (name, description, crs, version, tree_count, "
                     "created_unix_ms, updated_unix_ms) VALUES (?1, ?2, ?3, 1, 0, ?4, ?4)");
    insert.BindText(1, name);
    insert.BindText(2, description);
    insert.BindText(3, crs);
    insert.BindInt64(4, info.created_unix_ms);
    try {
      insert.Run();
    } catch (const StorageError& e) {
      if (e.code() != Code::kAlreadyExists) throw;  // UNIQUE(name)
      throw StorageError(Code::kAlreadyExists, "map '" + name + "' already exists");
    }
    transaction.Commit();
  });
  return info;
}

std::vector<MapInfo> SqliteMapStore::ListMaps() {
  std::vector<MapInfo> maps;
  WithReader([&](Database& db) {
    Statement select(db,
                     "SELECT id, name, description, crs, version, tree_count, min_x, min_y, "
                     "max_x, max_y, created_unix_ms, updated_unix_ms FROM maps ORDER BY name");
    while (select.Step()) maps.push_back(ReadMapRow(select).info);
  });
  return maps;
}

MapInfo SqliteMapStore::GetMap(const std::string& name) {
  CheckName(name);
  MapInfo info;
  WithReader([&](Database& db) { info = RequireMap(db, name).info; });
  return info;
}

void SqliteMapStore::DeleteMap(const std::string& name) {
  CheckName(name);
  WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    const MapRow map = RequireMap(db, name);
    DeleteTreesOfMap(db, map.id);
    Statement remove(db, "DELETE FROM maps WHERE id = ?1");
    remove.BindInt64(1, map.id);
    remove.Run();
    transaction.Commit();
  });
}

// ---- Trees ----

MapInfo SqliteMapStore::WriteTrees(const std::string& name, const std::vector<TreeRecord>& trees,
                                   WriteMode mode) {
  CheckName(name);
  const BatchSummary batch = CheckBatch(name, trees);
  MapInfo result;
  WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    MapRow map = RequireMap(db, name);
    const bool replace = mode == WriteMode::kReplace;
    if (trees.empty() && (!replace || map.info.tree_count == 0)) {
      result = map.info;  // nothing can change: keep the version
      return;
    }
    std::optional<int64_t> max_id = batch.max_explicit_id;
    if (replace) {
      DeleteTreesOfMap(db, map.id);
    } else {
      Statement max_existing(db, "SELECT MAX(tree_id) FROM trees WHERE map_id = ?1");
      max_existing.BindInt64(1, map.id);
      if (max_existing.Step() && !max_existing.ColumnIsNull(0)) {
        max_id = std::max(max_id.value_or(std::numeric_limits<int64_t>::min()),
                          max_existing.ColumnInt64(0));
      }
    }
    InsertTrees(db, map, trees, FirstAutoId(name, max_id, batch.auto_id_count));

    // The new count and extent follow from the old ones and the batch: no table scan needed.
    MapInfo& info = map.info;
    const auto count = static_cast<int64_t>(trees.size());
    info.tree_count = replace ? count : info.tree_count + count;
    info.extent = replace ? batch.extent : Union(info.extent, batch.extent);
    info.version += 1;
    info.updated_unix_ms = NowUnixMs();
    Statement update(db,
                     "UPDATE maps SET version = ?2, tree_count = ?3, min_x = ?4, min_y = ?5, "
                     "max_x = ?6, max_y = ?7, updated_unix_ms = ?8 WHERE id = ?1");
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
    update.Run();
    transaction.Commit();
    result = info;
  });
  return result;
}

MapSnapshot SqliteMapStore::ReadMap(const std::string& name) {
  CheckName(name);
  MapSnapshot snapshot;
  WithReader([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kRead);  // info and trees of one version
    const MapRow map = RequireMap(db, name);
    snapshot.info = map.info;
    snapshot.trees.reserve(static_cast<size_t>(map.info.tree_count));
    Statement select(db,
                     "SELECT tree_id, x, y, z, dbh, attributes FROM trees WHERE map_id = ?1 "
                     "ORDER BY tree_id");
    select.BindInt64(1, map.id);
    while (select.Step()) snapshot.trees.push_back(ReadTreeRow(select, name));
    transaction.Commit();
  });
  return snapshot;
}

std::vector<TreeRecord> SqliteMapStore::TreesInBox(const std::string& name, const Extent& box) {
  CheckName(name);
  if (std::isnan(box.min_x) || std::isnan(box.min_y) || std::isnan(box.max_x) ||
      std::isnan(box.max_y) || box.min_x > box.max_x || box.min_y > box.max_y) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': invalid box x [" + std::to_string(box.min_x) + ", " +
                           std::to_string(box.max_x) + "], y [" + std::to_string(box.min_y) + ", " +
                           std::to_string(box.max_y) +
                           "]: bounds must not be NaN and min must not exceed max");
  }
  std::vector<TreeRecord> trees;
  WithReader([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kRead);
    const MapRow map = RequireMap(db, name);
    // CROSS JOIN keeps the R*Tree as the outer loop: blocks near the box, then each block's rowid
    // range. The conditions on t filter the float32 superset exactly; the unary + keeps SQLite
    // from walking all trees of the map by the (map_id, tree_id) index instead of the range.
    Statement select(db,
                     "SELECT t.tree_id, t.x, t.y, t.z, t.dbh, t.attributes FROM tree_blocks AS b "
                     "CROSS JOIN trees AS t ON t.rowid BETWEEN b.first_rowid AND b.last_rowid "
                     "WHERE b.min_map <= ?1 AND b.max_map >= ?1 AND b.min_x <= ?3 AND "
                     "b.max_x >= ?2 AND b.min_y <= ?5 AND b.max_y >= ?4 AND b.map_id = ?1 AND "
                     "+t.map_id = ?1 AND t.x >= ?2 AND t.x <= ?3 AND t.y >= ?4 AND t.y <= ?5 "
                     "ORDER BY t.tree_id");
    select.BindInt64(1, map.id);
    select.BindDouble(2, box.min_x);
    select.BindDouble(3, box.max_x);
    select.BindDouble(4, box.min_y);
    select.BindDouble(5, box.max_y);
    while (select.Step()) {
      // Blocks never share rows, but should rowids ever be reused out of order (SQLite does so
      // only after rowid 2^63 - 1), a row could sit in two ranges: keep it once.
      TreeRecord tree = ReadTreeRow(select, name);
      if (trees.empty() || trees.back().id != tree.id) trees.push_back(std::move(tree));
    }
    transaction.Commit();
  });
  return trees;
}

}  // namespace forestmap::storage
