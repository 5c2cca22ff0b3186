// SqliteMapStore::PruneVersions: drops the history before the newest versions of a map.

#include <string>

#include "storage/sqlite/internal.h"

namespace forestmap::storage {

using Code = StorageError::Code;
using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;

namespace {

// Runs a DELETE with ?1 = map id and ?2 = the first kept version; returns the rows deleted.
int64_t DeleteBefore(Database& db, const char* sql, int64_t map_id, int64_t first_kept) {
  Statement remove(db, sql);
  remove.BindInt64(1, map_id);
  remove.BindInt64(2, first_kept);
  remove.Run();
  return db.Changes();
}

}  // namespace

PruneResult SqliteMapStore::PruneVersions(const std::string& name, int64_t keep) {
  internal::CheckName(name);
  if (keep < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "keep is " + std::to_string(keep) + "; at least the current version stays");
  }
  PruneResult result;
  WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    const internal::MapRow map = internal::RequireMap(db, name);
    result.info = map.info;
    const int64_t first_kept = map.info.version - keep + 1;
    if (first_kept <= 1) return;  // nothing older than what is kept
    // Rows no kept version holds: closed at or before the first kept version (not the pending
    // rows of an upload, whose valid_to is negative).
    result.tree_rows_removed =
        DeleteBefore(db, "DELETE FROM trees WHERE map_id = ?1 AND valid_to > 0 AND valid_to <= ?2",
                     map.id, first_kept);
    result.observation_rows_removed = DeleteBefore(
        db, "DELETE FROM observations WHERE map_id = ?1 AND valid_to <= ?2", map.id, first_kept);
    result.versions_removed = DeleteBefore(
        db, "DELETE FROM map_versions WHERE map_id = ?1 AND version < ?2", map.id, first_kept);
    // Spatial blocks whose rows are all gone.
    Statement blocks(db,
                     "DELETE FROM tree_blocks WHERE id IN (SELECT b.id FROM tree_blocks AS b "
                     "WHERE b.min_map <= ?1 AND b.max_map >= ?1 AND b.map_id = ?1 AND NOT EXISTS "
                     "(SELECT 1 FROM trees AS t WHERE t.rowid BETWEEN b.first_rowid AND "
                     "b.last_rowid))");
    blocks.BindInt64(1, map.id);
    blocks.Run();
    internal::CommitWrite(db, transaction, map.info);
  });
  return result;
}

}  // namespace forestmap::storage
