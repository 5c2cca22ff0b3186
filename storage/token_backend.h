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
