// The SQLite session (storage/store_backend.h): transactions, maps, history, prune and the
// request log. Tree and observation rows are in trees.cc and observations.cc.

#include <optional>
#include <string>
#include <vector>

#include "storage/sqlite/internal.h"

namespace forestmap::storage::sqlite {
namespace {

// Runs a DELETE with ?1 = map id and ?2 = the first kept version; returns the rows deleted.
int64_t DeleteBefore(Database& db, const char* sql, int64_t map_id, int64_t first_kept) {
  Statement(db, sql, map_id, first_kept).Run();
  return db.Changes();
}

}  // namespace

// ---- Transactions ----

// BEGIN IMMEDIATE for a write: the write lock (of the whole database) is taken before the first
// read, so what a write reads is the version its changes apply to.
void Session::Begin(TransactionKind kind) {
  transaction_.emplace(
      db_, kind == TransactionKind::kWrite ? Transaction::Kind::kWrite : Transaction::Kind::kRead);
}

void Session::Commit() {
  transaction_->Commit();
  transaction_.reset();
}

void Session::Rollback() noexcept { transaction_.reset(); }

// ---- Maps ----

// A map that an upload is still creating (creating_upload set) does not exist yet.
std::vector<MapInfo> Session::ListMaps() {
  Statement select(db_, "SELECT " FORESTMAP_MAP_COLUMNS
                        " FROM maps WHERE creating_upload IS NULL ORDER BY name");
  return ReadAll(select, [](const Row& row) { return internal::ReadMapRow(row).info; });
}

std::optional<MapRow> Session::FindMap(const std::string& name) {
  Statement select(
      db_, "SELECT " FORESTMAP_MAP_COLUMNS " FROM maps WHERE name = ?1 AND creating_upload IS NULL",
      name);
  if (!select.Step()) return std::nullopt;
  return internal::ReadMapRow(Row(select));
}

bool Session::LockMap(int64_t /*map_id*/) { return false; }  // BEGIN IMMEDIATE holds it

int64_t Session::InsertMap(const MapInfo& info) {
  Statement(db_,
            "INSERT INTO maps (name, description, crs, version, tree_count, created_unix_ms, "
            "updated_unix_ms) VALUES (?1, ?2, ?3, 1, 0, ?4, ?4)",
            info.name, info.description, info.crs, info.created_unix_ms)
      .Run();
  return db_.LastInsertRowId();
}

// ON DELETE CASCADE does not reach the R*Tree: the map's blocks go first, by hand.
void Session::DeleteMap(const MapRow& map) {
  for (const char* sql :
       {"DELETE FROM tree_blocks WHERE min_map <= ?1 AND max_map >= ?1 AND map_id = ?1",
        "DELETE FROM trees WHERE map_id = ?1", "DELETE FROM observations WHERE map_id = ?1",
        "DELETE FROM map_versions WHERE map_id = ?1",
        "DELETE FROM map_boundaries WHERE map_id = ?1", "DELETE FROM map_columns WHERE map_id = ?1",
        "DELETE FROM tree_removals WHERE map_id = ?1", "DELETE FROM maps WHERE id = ?1"}) {
    Statement(db_, sql, map.id).Run();
  }
}

void Session::UpdateMap(const MapRow& map) {
  Statement update(db_,
                   "UPDATE maps SET version = ?2, tree_count = ?3, min_x = ?4, min_y = ?5, "
                   "max_x = ?6, max_y = ?7, updated_unix_ms = ?8, confirmed_count = ?9 "
                   "WHERE id = ?1",
                   map.id);
  Binder values(update, 2);
  internal::WriteMapValues(values, map.info);
  update.Run();
}

std::optional<Extent> Session::ScanExtent(int64_t map_id) {
  Statement scan(db_,
                 "SELECT MIN(x), MIN(y), MAX(x), MAX(y) FROM trees INDEXED BY trees_current "
                 "WHERE map_id = ?1 AND valid_to = " FORESTMAP_CURRENT,
                 map_id);
  if (!scan.Step() || scan.ColumnIsNull(0)) return std::nullopt;
  return Extent{scan.ColumnDouble(0), scan.ColumnDouble(1), scan.ColumnDouble(2),
                scan.ColumnDouble(3)};
}

// ---- History ----

void Session::InsertVersion(int64_t map_id, const VersionRecord& record) {
  Statement insert(db_,
                   "INSERT INTO map_versions (map_id, " FORESTMAP_VERSION_COLUMNS
                   ") VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13)",
                   map_id);
  Binder values(insert, 2);
  internal::WriteVersionValues(values, record);
  insert.Run();
}

std::optional<VersionRecord> Session::FindVersion(int64_t map_id, int64_t version) {
  Statement select(db_,
                   "SELECT " FORESTMAP_VERSION_COLUMNS
                   " FROM map_versions WHERE map_id = ?1 AND version = ?2",
                   map_id, version);
  if (!select.Step()) return std::nullopt;
  return internal::ReadVersionRow(Row(select));
}

std::optional<int64_t> Session::OldestVersion(int64_t map_id) {
  return Statement(db_, "SELECT MIN(version) FROM map_versions WHERE map_id = ?1", map_id)
      .OptionalInt64();
}

std::vector<int64_t> Session::NewestVersions(int64_t map_id, int64_t limit) {
  Statement select(
      db_, "SELECT version FROM map_versions WHERE map_id = ?1 ORDER BY version DESC LIMIT ?2",
      map_id, limit > 0 ? limit : -1);
  return ReadAll(select, [](const Row& row) { return row.Int64(0); });
}

PrunedRows Session::PruneBefore(int64_t map_id, int64_t first_kept) {
  PrunedRows pruned;
  // Rows no kept version holds: closed at or before the first kept version (not the pending
  // rows of an upload, whose valid_to is negative).
  pruned.trees =
      DeleteBefore(db_, "DELETE FROM trees WHERE map_id = ?1 AND valid_to > 0 AND valid_to <= ?2",
                   map_id, first_kept);
  pruned.observations = DeleteBefore(
      db_, "DELETE FROM observations WHERE map_id = ?1 AND valid_to <= ?2", map_id, first_kept);
  pruned.versions = DeleteBefore(db_, "DELETE FROM map_versions WHERE map_id = ?1 AND version < ?2",
                                 map_id, first_kept);
  // Boundary and column-order rows before the ones in force at the first kept version.
  for (const char* sql :
       {"DELETE FROM map_boundaries WHERE map_id = ?1 AND version < (SELECT MAX(version) FROM "
        "map_boundaries WHERE map_id = ?1 AND version <= ?2)",
        "DELETE FROM map_columns WHERE map_id = ?1 AND version < (SELECT MAX(version) FROM "
        "map_columns WHERE map_id = ?1 AND version <= ?2)",
        "DELETE FROM tree_removals WHERE map_id = ?1 AND version < ?2"}) {
    Statement(db_, sql, map_id, first_kept).Run();
  }
  // Spatial blocks whose rows are all gone.
  Statement(db_,
            "DELETE FROM tree_blocks WHERE id IN (SELECT b.id FROM tree_blocks AS b WHERE "
            "b.min_map <= ?1 AND b.max_map >= ?1 AND b.map_id = ?1 AND NOT EXISTS (SELECT 1 "
            "FROM trees AS t WHERE t.rowid BETWEEN b.first_rowid AND b.last_rowid))",
            map_id)
      .Run();
  return pruned;
}

// ---- Survey boundary ----

std::string Session::BoundaryAt(int64_t map_id, int64_t version) {
  Statement select(db_,
                   "SELECT polygons FROM map_boundaries WHERE map_id = ?1 AND version <= ?2 "
                   "ORDER BY version DESC LIMIT 1",
                   map_id, version);
  return select.Step() ? select.ColumnText(0) : std::string();
}

void Session::InsertBoundary(int64_t map_id, int64_t version, const std::string& encoded) {
  Statement insert(db_,
                   "INSERT OR REPLACE INTO map_boundaries (map_id, version, polygons) "
                   "VALUES (?1, ?2, ?3)",
                   map_id, version);
  insert.BindText(3, encoded);
  insert.Run();
}

// ---- Order of the attribute columns ----

std::string Session::ColumnsAt(int64_t map_id, int64_t version) {
  Statement select(db_,
                   "SELECT names FROM map_columns WHERE map_id = ?1 AND version <= ?2 "
                   "ORDER BY version DESC LIMIT 1",
                   map_id, version);
  return select.Step() ? select.ColumnText(0) : std::string();
}

void Session::InsertColumns(int64_t map_id, int64_t version, const std::string& encoded) {
  Statement insert(
      db_, "INSERT OR REPLACE INTO map_columns (map_id, version, names) VALUES (?1, ?2, ?3)",
      map_id, version);
  insert.BindText(3, encoded);
  insert.Run();
}

// ---- Removal log ----

void Session::InsertRemovals(int64_t map_id, int64_t version,
                             const std::vector<TreeRemoval>& removals) {
  if (removals.empty()) return;
  Statement insert(db_,
                   "INSERT INTO tree_removals (map_id, version, tree_id, evidence) VALUES "
                   "(?1, ?2, ?3, ?4)",
                   map_id, version);
  for (const TreeRemoval& removal : removals) {
    insert.BindInt64(3, removal.tree_id);
    insert.BindText(4, removal.evidence);
    insert.Run();
  }
}

std::vector<TreeRemoval> Session::RemovalsAfter(int64_t map_id, int64_t after_version) {
  Statement select(db_,
                   "SELECT version, tree_id, evidence FROM tree_removals WHERE map_id = ?1 AND "
                   "version > ?2 ORDER BY version, tree_id",
                   map_id, after_version);
  std::vector<TreeRemoval> removals;
  while (select.Step()) {
    removals.push_back({select.ColumnInt64(1), select.ColumnText(2), select.ColumnInt64(0)});
  }
  return removals;
}

// ---- Request log ----

void Session::ExpireRequests(int64_t before_unix_ms) {
  Statement(db_, "DELETE FROM request_log WHERE created_unix_ms < ?1", before_unix_ms).Run();
}

bool Session::InsertRequest(const std::string& id, const StoredRequest& answer) {
  Statement insert(db_,
                   "INSERT INTO request_log (request_id, rpc, response, created_unix_ms, "
                   "fingerprint) VALUES (?1, ?2, ?3, ?4, ?5) ON CONFLICT (request_id) DO NOTHING",
                   id, answer.rpc);
  insert.BindBlob(3, answer.response);
  insert.BindInt64(4, answer.created_unix_ms);
  insert.BindText(5, answer.fingerprint);
  insert.Run();
  return db_.Changes() != 0;
}

std::optional<StoredRequest> Session::FindRequest(const std::string& id) {
  Statement select(db_,
                   "SELECT rpc, response, created_unix_ms, fingerprint FROM request_log "
                   "WHERE request_id = ?1",
                   id);
  if (!select.Step()) return std::nullopt;
  return StoredRequest{select.ColumnText(0), select.ColumnBlob(1), select.ColumnInt64(2),
                       select.ColumnText(3)};
}

}  // namespace forestmap::storage::sqlite
