// Access tokens on PostgreSQL: the same rows as the SQLite table access_tokens, in a
// table of the same name made on first use (CREATE TABLE IF NOT EXISTS under an advisory lock, so
// replicas starting together make it once). Kept out of the map schema's steps on purpose: the
// table is the token store's alone and needs no migration of the maps.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"
#include "storage/postgres/internal.h"
#include "storage/token_backend.h"

namespace forestmap::storage {
namespace {

using pg::Connection;
using pg::Params;

constexpr int kConnections = 2;                      // token checks are one short query each
constexpr int64_t kTableLockKey = 0x466d546f6b656e;  // advisory lock key: "FmToken"

constexpr const char* kCreateTable =
    "CREATE TABLE IF NOT EXISTS access_tokens ("
    " id BIGSERIAL PRIMARY KEY,"
    " secret_sha256 TEXT NOT NULL UNIQUE,"
    " map_pattern TEXT NOT NULL,"
    " role INTEGER NOT NULL CHECK (role BETWEEN 1 AND 3),"
    " note TEXT NOT NULL DEFAULT '',"
    " created_unix_ms BIGINT NOT NULL,"
    " revoked_unix_ms BIGINT);"
    // Tables made before tokens could expire gain the column (NULL: never).
    "ALTER TABLE access_tokens ADD COLUMN IF NOT EXISTS expires_unix_ms BIGINT";

class PostgresTokens final : public TokenBackend {
 public:
  explicit PostgresTokens(const std::string& conninfo)
      : pool_([conninfo] { return std::make_unique<Connection>(conninfo); }, kConnections,
              [](const Connection& conn) { return conn.healthy(); }) {
    pool_.With([](Connection& conn) {
      pg::Transaction transaction(conn, pg::Transaction::Kind::kWrite);
      conn.Exec("SELECT pg_advisory_xact_lock($1)", Params().Int64(kTableLockKey));
      conn.ExecScript(kCreateTable);
      transaction.Commit();
    });
  }

  int64_t Insert(const std::string& secret_sha256, const TokenRecord& record) override {
    int64_t id = 0;
    pool_.With([&](Connection& conn) {
      const pg::Result rows = conn.Exec(
          "INSERT INTO access_tokens (secret_sha256, map_pattern, role, note, created_unix_ms, "
          "expires_unix_ms) VALUES ($1, $2, $3, $4, $5, NULLIF($6::bigint, 0)) RETURNING id",
          Params()
              .Text(secret_sha256)
              .Text(record.map_pattern)
              .Int64(static_cast<int64_t>(record.role))
              .Text(record.note)
              .Int64(record.created_unix_ms)
              .Int64(record.expires_unix_ms));
      id = rows.Int64(0, 0);
    });
    return id;
  }

  std::vector<TokenRecord> List() override {
    std::vector<TokenRecord> records;
    pool_.With([&](Connection& conn) {
      const pg::Result rows =
          conn.Exec("SELECT " FORESTMAP_TOKEN_COLUMNS " FROM access_tokens ORDER BY id");
      records = pg::ReadAll(rows, [](const pg::Row& row) { return ReadTokenRow(row); });
    });
    return records;
  }

  bool Revoke(int64_t id, int64_t now_unix_ms) override {
    bool revoked = false;
    pool_.With([&](Connection& conn) {
      revoked = conn.Exec(
                        "UPDATE access_tokens SET revoked_unix_ms = $1 "
                        "WHERE id = $2 AND revoked_unix_ms IS NULL",
                        Params().Int64(now_unix_ms).Int64(id))
                    .affected() == 1;
    });
    return revoked;
  }

  std::optional<TokenRecord> FindValid(const std::string& secret_sha256) override {
    std::optional<TokenRecord> found;
    pool_.With([&](Connection& conn) {
      const pg::Result rows = conn.Exec("SELECT " FORESTMAP_TOKEN_COLUMNS
                                        " FROM access_tokens WHERE secret_sha256 = $1 AND "
                                        "revoked_unix_ms IS NULL",
                                        Params().Text(secret_sha256));
      if (rows.rows() > 0) found = ReadTokenRow(pg::Row(rows, 0));
    });
    return found;
  }

  bool AnyToken() override {
    bool any = false;
    pool_.With([&](Connection& conn) {
      any = conn.Exec("SELECT EXISTS (SELECT 1 FROM access_tokens)").Bool(0, 0);
    });
    return any;
  }

 private:
  ConnectionPool<Connection> pool_;
};

}  // namespace

std::unique_ptr<TokenBackend> OpenPostgresTokens(const std::string& conninfo) {
  return std::make_unique<PostgresTokens>(conninfo);
}

}  // namespace forestmap::storage
