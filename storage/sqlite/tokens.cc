// Access tokens in the server's SQLite file (table access_tokens, schema step 5): one connection,
// one mutex; each call is one short statement.

#include <sqlite3.h>

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "storage/sqlite/internal.h"
#include "storage/token_backend.h"

namespace forestmap::storage {
namespace {

using sqlite::Row;

// Tokens in the server's SQLite file: one connection, one mutex.
class SqliteTokens final : public TokenBackend {
 public:
  SqliteTokens(const std::string& path, int busy_timeout_ms) {
    db_ = std::make_unique<sqlite::Database>(
        path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, busy_timeout_ms);
    sqlite::MigrateSchema(*db_, sqlite::SchemaSteps());
    if (path != ":memory:") db_->EnableWal();
  }

  int64_t Insert(const std::string& secret_sha256, const TokenRecord& record) override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement(*db_,
                      "INSERT INTO access_tokens (secret_sha256, map_pattern, role, note, "
                      "created_unix_ms, expires_unix_ms) VALUES (?1, ?2, ?3, ?4, ?5, "
                      "NULLIF(?6, 0))",
                      secret_sha256, record.map_pattern, static_cast<int64_t>(record.role),
                      record.note, record.created_unix_ms, record.expires_unix_ms)
        .Run();
    return db_->LastInsertRowId();
  }

  std::vector<TokenRecord> List() override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement query(*db_,
                            "SELECT " FORESTMAP_TOKEN_COLUMNS " FROM access_tokens ORDER BY id");
    return sqlite::ReadAll(query, [](const Row& row) { return ReadTokenRow(row); });
  }

  bool Revoke(int64_t id, int64_t now_unix_ms) override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement(*db_,
                      "UPDATE access_tokens SET revoked_unix_ms = ?1 WHERE id = ?2 AND "
                      "revoked_unix_ms IS NULL",
                      now_unix_ms, id)
        .Run();
    return db_->Changes() == 1;
  }

  std::optional<TokenRecord> FindValid(const std::string& secret_sha256) override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement query(*db_,
                            "SELECT " FORESTMAP_TOKEN_COLUMNS
                            " FROM access_tokens WHERE secret_sha256 = ?1 AND "
                            "revoked_unix_ms IS NULL",
                            secret_sha256);
    if (!query.Step()) return std::nullopt;
    return ReadTokenRow(Row(query));
  }

  bool AnyToken() override {
    std::lock_guard<std::mutex> lock(mutex_);
    return db_->QueryInt64("SELECT EXISTS (SELECT 1 FROM access_tokens)") != 0;
  }

 private:
  std::mutex mutex_;
  std::unique_ptr<sqlite::Database> db_;
};

}  // namespace

std::unique_ptr<TokenBackend> OpenSqliteTokens(const std::string& path, int busy_timeout_ms) {
  return std::make_unique<SqliteTokens>(path, busy_timeout_ms);
}

}  // namespace forestmap::storage
