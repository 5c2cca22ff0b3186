// SqliteMapStore: the request log of exactly-once writes (storage/write_request.h).

#include <chrono>
#include <string>

#include "storage/sqlite/internal.h"

namespace forestmap::storage {

using Code = StorageError::Code;
using sqlite::Database;
using sqlite::Statement;

namespace internal {

void CommitWrite(Database& db, sqlite::Transaction& transaction, const MapInfo& info) {
  const WriteRequest* request = CurrentWriteRequest();
  if (request != nullptr) {
    if (!request->id.empty()) {
      const int64_t now = NowUnixMs();
      Statement expire(db, "DELETE FROM request_log WHERE created_unix_ms < ?1");
      expire.BindInt64(1, now - kRequestLogRetentionMs);
      expire.Run();
      Statement insert(db,
                       "INSERT INTO request_log (request_id, rpc, response, created_unix_ms) "
                       "VALUES (?1, ?2, ?3, ?4) ON CONFLICT (request_id) DO NOTHING");
      insert.BindText(1, request->id);
      insert.BindText(2, request->rpc);
      insert.BindBlob(3, request->encode ? request->encode(info) : std::string());
      insert.BindInt64(4, now);
      insert.Run();
      if (db.Changes() == 0) ThrowAppliedConcurrently(*request);
    }
    CheckDeadlineBeforeCommit(*request);  // as close to COMMIT as possible
  }
  transaction.Commit();
}

}  // namespace internal

std::optional<StoredRequest> SqliteMapStore::FindRequest(const std::string& request_id) {
  std::optional<StoredRequest> found;
  WithReader([&](Database& db) {
    Statement select(db,
                     "SELECT rpc, response, created_unix_ms FROM request_log "
                     "WHERE request_id = ?1");
    select.BindText(1, request_id);
    if (select.Step()) {
      found = StoredRequest{select.ColumnText(0), select.ColumnBlob(1), select.ColumnInt64(2)};
    }
  });
  return found;
}

}  // namespace forestmap::storage
