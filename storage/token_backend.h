#pragma once
// Where TokenStore (storage/token_store.h) keeps its rows: the SQLite file of the server
// (table access_tokens of the map schema) or a PostgreSQL database (table access_tokens, created
// on first use, storage/postgres/tokens.cc). Values come checked and hashed from TokenStore.
// Thread-safety: every method may be called from many threads at once.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "storage/token_store.h"

namespace forestmap::storage {

// Columns of every token query, in the order ReadTokenRow expects; `Row` as in storage/rows.h.
#define FORESTMAP_TOKEN_COLUMNS \
  "id, map_pattern, role, note, created_unix_ms, revoked_unix_ms, expires_unix_ms"
template <typename Row>
TokenRecord ReadTokenRow(const Row& row) {
  TokenRecord record;
  record.id = row.Int64(0);
  record.map_pattern = row.Text(1);
  record.role = static_cast<Role>(row.Int64(2));
  record.note = row.Text(3);
  record.created_unix_ms = row.Int64(4);
  record.revoked_unix_ms = row.IsNull(5) ? 0 : row.Int64(5);
  record.expires_unix_ms = row.IsNull(6) ? 0 : row.Int64(6);
  return record;
}

class TokenBackend {
 public:
  virtual ~TokenBackend() = default;
  // Stores `record` (its id is ignored) under `secret_sha256`; returns the new id.
  virtual int64_t Insert(const std::string& secret_sha256, const TokenRecord& record) = 0;
  virtual std::vector<TokenRecord> List() = 0;  // by id
  // Sets revoked_unix_ms of a valid token; false when none was changed.
  virtual bool Revoke(int64_t id, int64_t now_unix_ms) = 0;
  virtual std::optional<TokenRecord> FindValid(const std::string& secret_sha256) = 0;
  virtual bool AnyToken() = 0;
};

// The backend of the database `db` names (as OpenMapStore: a postgresql:// URI or a SQLite file
// path), storage/open_store.cc. Throws StorageError.
std::unique_ptr<TokenBackend> OpenTokenBackend(const std::string& db, int busy_timeout_ms);

}  // namespace forestmap::storage
