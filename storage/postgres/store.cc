#include "storage/postgres/store.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include "storage/checks.h"
#include "storage/postgres/connection.h"
#include "storage/postgres/internal.h"
#include "storage/store_steps.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;
using pg::Connection;
using pg::Params;
using pg::Transaction;
using pg_internal::MapRow;

// Closes every current tree and observation row of a map at `version`; returns the number of
// observation rows closed.
int64_t CloseAllCurrentRows(Connection& conn, int64_t map_id, int64_t version) {
  const Params close = Params().Int64(map_id).Int64(version);
  conn.Exec("UPDATE trees SET valid_to = $2 WHERE map_id = $1 AND valid_to = " FORESTMAP_PG_CURRENT,
            close);
  return conn
      .Exec(
          "UPDATE observations SET valid_to = $2 WHERE map_id = $1 AND "
          "valid_to = " FORESTMAP_PG_CURRENT,
          close)
      .affected();
}

}  // namespace

void PostgresMapStoreOptions::Check() const {
  if (max_connections < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "PostgresMapStoreOptions: max_connections must be >= 1");
  }
}

PostgresMapStore::PostgresMapStore(const std::string& conninfo,
                                   const PostgresMapStoreOptions& options)
    : options_(options), conninfo_(conninfo) {
  options_.Check();
  pool_ = std::make_unique<pg::ConnectionPool>(conninfo, options_.max_connections);
  if (static_cast<int64_t>(pg_internal::SchemaSteps().size()) != kSchemaVersion) {
    throw StorageError(Code::kInternal, "schema steps and kSchemaVersion disagree");
  }
  With([](Connection& conn) { pg::MigrateSchema(conn, pg_internal::SchemaSteps()); });
}

PostgresMapStore::~PostgresMapStore() = default;

void PostgresMapStore::With(const Body& body) { pool_->With(body); }

MapInfo PostgresMapStore::CreateMap(const std::string& name, const std::string& description,
                                    const std::string& crs) {
  internal::CheckName(name);
  const MapInfo info = internal::NewMapInfo(name, description, crs);
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kWrite);
    int64_t id = 0;
    try {
      id = conn.Exec(
                   "INSERT INTO maps (name, description, crs, version, tree_count, "
                   "created_unix_ms, updated_unix_ms) VALUES ($1, $2, $3, 1, 0, $4, $4) "
                   "RETURNING id",
                   Params().Text(name).Text(description).Text(crs).Int64(info.created_unix_ms))
               .Int64(0, 0);
    } catch (const StorageError& e) {
      if (e.code() != Code::kAlreadyExists) throw;  // UNIQUE(name)
      throw StorageError(Code::kAlreadyExists, "map '" + name + "' already exists");
    }
    pg_internal::InsertVersion(conn, id, internal::CreationRecord(info));
    pg_internal::CommitWrite(conn, transaction, info);
  });
  return info;
}

std::vector<MapInfo> PostgresMapStore::ListMaps() {
  std::vector<MapInfo> maps;
  With([&](Connection& conn) {
    const pg::Result result =
        conn.Exec("SELECT " FORESTMAP_PG_MAP_COLUMNS " FROM maps ORDER BY name");
    for (int r = 0; r < result.rows(); ++r) maps.push_back(pg_internal::ReadMapRow(result, r).info);
  });
  return maps;
}

MapInfo PostgresMapStore::GetMap(const std::string& name) {
  internal::CheckName(name);
  MapInfo info;
  With([&](Connection& conn) { info = pg_internal::RequireMap(conn, name).info; });
  return info;
}

void PostgresMapStore::DeleteMap(const std::string& name) {
  internal::CheckName(name);
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kWrite);
    const MapRow map = pg_internal::LockMap(conn, name);
    // Trees, observations and history go with it (ON DELETE CASCADE).
    conn.Exec("DELETE FROM maps WHERE id = $1", Params().Int64(map.id));
    pg_internal::CommitWrite(conn, transaction, map.info);
  });
}

MapInfo PostgresMapStore::WriteTrees(const std::string& name, const std::vector<TreeRecord>& trees,
                                     WriteMode mode) {
  internal::CheckName(name);
  const internal::BatchSummary batch = internal::CheckBatch(name, trees);
  MapInfo result;
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kWrite);
    MapRow map = pg_internal::LockMap(conn, name);
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
      record.observations_removed = CloseAllCurrentRows(conn, map.id, record.version);
    } else {
      const pg::Result max_existing = conn.Exec(
          "SELECT MAX(tree_id) FROM trees WHERE map_id = $1 AND valid_to = " FORESTMAP_PG_CURRENT,
          Params().Int64(map.id));
      if (!max_existing.IsNull(0, 0)) max_id = internal::MaxId(max_id, max_existing.Int64(0, 0));
    }
    const std::vector<int64_t> ids = internal::AssignIds(name, trees, max_id, batch.auto_id_count);
    pg_internal::InsertTrees(conn, map, trees, ids, record.version);
    internal::StampWrittenBatch(map.info, record, trees, batch, replace);
    pg_internal::UpdateMapRow(conn, map);
    pg_internal::InsertVersion(conn, map.id, record);
    pg_internal::CommitWrite(conn, transaction, map.info);
    result = map.info;
  });
  return result;
}

MapSnapshot PostgresMapStore::ReadMap(const std::string& name) { return ReadMapVersion(name, 0); }

std::vector<TreeRecord> PostgresMapStore::TreesInBox(const std::string& name, const Extent& box) {
  internal::CheckName(name);
  internal::CheckBox(name, box);
  std::vector<TreeRecord> trees;
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kRead);
    const MapRow map = pg_internal::RequireMap(conn, name);
    trees = pg_internal::CurrentTreesInBox(conn, map, box);
    transaction.Commit();
  });
  return trees;
}

}  // namespace forestmap::storage
