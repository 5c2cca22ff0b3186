#include "storage/open_store.h"

#include <memory>
#include <string>

#include "storage/postgres/connection.h"
#include "storage/postgres/store.h"
#include "storage/sqlite/store.h"
#include "storage/token_backend.h"

namespace forestmap::storage {

bool IsPostgresUri(const std::string& db) {
  return db.rfind("postgresql://", 0) == 0 || db.rfind("postgres://", 0) == 0;
}

std::string DescribeDatabase(const std::string& db) {
  return IsPostgresUri(db) ? "postgresql " + pg::DescribeServer(db) : db;
}

std::unique_ptr<MapStore> OpenMapStore(const std::string& db, int64_t max_db_mib) {
  if (IsPostgresUri(db)) {
    if (max_db_mib != 0) {
      throw StorageError(StorageError::Code::kInvalidArgument,
                         "a database size limit applies to SQLite only; limit a PostgreSQL "
                         "database on its server (tablespace, quota)");
    }
    return std::make_unique<PostgresMapStore>(db);
  }
  SqliteMapStoreOptions options;
  options.max_db_mib = max_db_mib;
  options.reserve_mib = kServerReserveMib;
  return std::make_unique<SqliteMapStore>(db, options);
}

std::unique_ptr<TokenBackend> OpenTokenBackend(const std::string& db, int busy_timeout_ms) {
  if (IsPostgresUri(db)) return OpenPostgresTokens(db);
  return OpenSqliteTokens(db, busy_timeout_ms);
}

}  // namespace forestmap::storage
