#include "storage/sqlite/store.h"

#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include "storage/checks.h"
#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"
#include "storage/store_steps.h"

namespace forestmap::storage {
namespace {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;
using Code = StorageError::Code;
using internal::kForever;
using internal::MapRow;
using internal::RequireMap;
using internal::TreeLabel;
using internal::Union;

// ---- Writing trees ----

void DeleteTreesOfMap(Database& db, int64_t map_id) {
  Statement blocks(db,
                   "DELETE FROM tree_blocks WHERE min_map <= ?1 AND max_map >= ?1 AND "
                   "map_id = ?1");
  blocks.BindInt64(1, map_id);
  blocks.Run();
  for (const char* sql :
       {"DELETE FROM trees WHERE map_id = ?1", "DELETE FROM observations WHERE map_id = ?1",
        "DELETE FROM map_versions WHERE map_id = ?1"}) {
    Statement remove(db, sql);
    remove.BindInt64(1, map_id);
    remove.Run();
  }
}

}  // namespace

void SqliteMapStoreOptions::Check() const {
  const auto fail = [](const std::string& message) {
    throw StorageError(Code::kInvalidArgument, "SqliteMapStoreOptions: " + message);
  };
  if (busy_timeout_ms < 0) fail("busy_timeout_ms must be >= 0");
  if (max_readers < 1) fail("max_readers must be >= 1");
  if (cache_mib < 1 || cache_mib > 1024 * 1024) fail("cache_mib must be in [1, 1048576]");
  if (max_db_mib < 0) fail("max_db_mib must be >= 0 (0: no limit)");
}

// ---- Connections ----

SqliteMapStore::SqliteMapStore(const std::string& path, const SqliteMapStoreOptions& options) try
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
  internal::ConfigureConnection(*writer_, options_, /*read_only=*/false);
  if (static_cast<int64_t>(internal::SchemaSteps().size()) != kSchemaVersion) {
    throw StorageError(StorageError::Code::kInternal, "schema steps and kSchemaVersion disagree");
  }
  // Refuses a database of something else, and a newer schema, before any change.
  internal::RefuseForeignDatabase(*writer_);
  sqlite::MigrateSchema(*writer_, internal::SchemaSteps());
  internal::RemoveAbandonedUploads(*writer_);
  if (path == ":memory:") return;  // the database exists on this one connection only
  writer_->EnableWal();
  internal::RefuseReadOnlyDatabase(*writer_);
  const SqliteMapStoreOptions reader_options = options_;
  readers_ = std::make_unique<sqlite::ConnectionPool>(
      [path, reader_options] {
        auto reader = std::make_unique<Database>(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX,
                                                 reader_options.busy_timeout_ms);
        internal::ConfigureConnection(*reader, reader_options, /*read_only=*/true);
        return reader;
      },
      options_.max_readers);
} catch (const StorageError& e) {
  // Any step that had to write (settings, migration, WAL, the probe) names the cause.
  if (e.code() == Code::kReadOnly) internal::ThrowReadOnly(path, e.what());
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
  internal::CheckName(name);
  const MapInfo info = internal::NewMapInfo(name, description, crs);
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
    internal::InsertVersion(db, db.LastInsertRowId(), internal::CreationRecord(info));
    internal::CommitWrite(db, transaction, info);
  });
  return info;
}

std::vector<MapInfo> SqliteMapStore::ListMaps() {
  std::vector<MapInfo> maps;
  WithReader([&](Database& db) {
    Statement select(db, "SELECT " FORESTMAP_MAP_COLUMNS
                         " FROM maps WHERE creating_upload IS NULL ORDER BY name");
    while (select.Step()) maps.push_back(internal::ReadMapRow(select).info);
  });
  return maps;
}

MapInfo SqliteMapStore::GetMap(const std::string& name) {
  internal::CheckName(name);
  MapInfo info;
  WithReader([&](Database& db) { info = RequireMap(db, name).info; });
  return info;
}

void SqliteMapStore::DeleteMap(const std::string& name) {
  internal::CheckName(name);
  WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    const MapRow map = RequireMap(db, name);
    DeleteTreesOfMap(db, map.id);
    Statement remove(db, "DELETE FROM maps WHERE id = ?1");
    remove.BindInt64(1, map.id);
    remove.Run();
    internal::CommitWrite(db, transaction, map.info);
  });
}

// ---- Trees ----

int64_t internal::CloseAllCurrentRows(Database& db, int64_t map_id, int64_t version) {
  Statement trees(
      db, "UPDATE trees SET valid_to = ?2 WHERE map_id = ?1 AND valid_to = " FORESTMAP_CURRENT);
  trees.BindInt64(1, map_id);
  trees.BindInt64(2, version);
  trees.Run();
  Statement observations(db,
                         "UPDATE observations SET valid_to = ?2 WHERE map_id = ?1 AND "
                         "valid_to = " FORESTMAP_CURRENT);
  observations.BindInt64(1, map_id);
  observations.BindInt64(2, version);
  observations.Run();
  return sqlite3_changes64(db.handle());
}

MapInfo SqliteMapStore::WriteTrees(const std::string& name, const std::vector<TreeRecord>& trees,
                                   WriteMode mode) {
  internal::CheckName(name);
  const internal::BatchSummary batch = internal::CheckBatch(name, trees);
  MapInfo result;
  WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    MapRow map = RequireMap(db, name);
    const bool replace = mode == WriteMode::kReplace;
    if (internal::WriteChangesNothing(trees, replace, map.info)) {
      result = map.info;  // nothing can change: keep the version
      return;
    }
    VersionRecord record =
        internal::NextVersion(map.info, replace ? VersionKind::kReplace : VersionKind::kUpload);
    std::optional<int64_t> max_id = batch.max_explicit_id;
    if (replace) {
      record.trees_removed = map.info.tree_count;
      record.observations_removed = internal::CloseAllCurrentRows(db, map.id, record.version);
    } else {
      Statement max_existing(db,
                             "SELECT MAX(tree_id) FROM trees INDEXED BY trees_current WHERE "
                             "map_id = ?1 AND valid_to = " FORESTMAP_CURRENT);
      max_existing.BindInt64(1, map.id);
      if (max_existing.Step() && !max_existing.ColumnIsNull(0)) {
        max_id = internal::MaxId(max_id, max_existing.ColumnInt64(0));
      }
    }
    const std::vector<int64_t> ids = internal::AssignIds(name, trees, max_id, batch.auto_id_count);
    internal::InsertTrees(db, map, trees, ids, record.version);
    internal::StampWrittenBatch(map.info, record, trees, batch, replace);
    internal::UpdateMapRow(db, map);
    internal::InsertVersion(db, map.id, record);
    internal::CommitWrite(db, transaction, map.info);
    result = map.info;
  });
  return result;
}

MapSnapshot SqliteMapStore::ReadMap(const std::string& name) { return ReadMapVersion(name, 0); }

std::vector<TreeRecord> SqliteMapStore::TreesInBox(const std::string& name, const Extent& box) {
  internal::CheckName(name);
  internal::CheckBox(name, box);
  std::vector<TreeRecord> trees;
  WithReader([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kRead);
    const MapRow map = RequireMap(db, name);
    trees = internal::CurrentTreesInBox(db, map, box);
    transaction.Commit();
  });
  return trees;
}

namespace internal {

std::vector<TreeRecord> CurrentTreesInBox(Database& db, const MapRow& map, const Extent& box) {
  // CROSS JOIN keeps the R*Tree as the outer loop: blocks near the box, then each block's rowid
  // range. The conditions on t filter the float32 superset exactly and drop rows of older
  // versions; the unary + keeps SQLite from walking all trees of the map by an index on map_id
  // instead of the range.
  Statement select(db, "SELECT " FORESTMAP_TREE_COLUMNS
                       " FROM tree_blocks AS b "
                       "CROSS JOIN trees AS t ON t.rowid BETWEEN b.first_rowid AND b.last_rowid "
                       "WHERE b.min_map <= ?1 AND b.max_map >= ?1 AND b.min_x <= ?3 AND "
                       "b.max_x >= ?2 AND b.min_y <= ?5 AND b.max_y >= ?4 AND b.map_id = ?1 AND "
                       "+t.map_id = ?1 AND +t.valid_to = " FORESTMAP_CURRENT
                       " AND t.x >= ?2 AND "
                       "t.x <= ?3 AND t.y >= ?4 AND t.y <= ?5 ORDER BY t.tree_id");
  select.BindInt64(1, map.id);
  select.BindDouble(2, box.min_x);
  select.BindDouble(3, box.max_x);
  select.BindDouble(4, box.min_y);
  select.BindDouble(5, box.max_y);
  std::vector<TreeRecord> trees;
  while (select.Step()) {
    // Blocks never share rows, but should rowids ever be reused out of order (SQLite does so
    // only after rowid 2^63 - 1), a row could sit in two ranges: keep it once.
    TreeRecord tree = internal::ReadTreeRow(select, map.info.name);
    if (trees.empty() || trees.back().id != tree.id) trees.push_back(std::move(tree));
  }
  return trees;
}

}  // namespace internal
}  // namespace forestmap::storage
