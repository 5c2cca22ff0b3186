#pragma once
// MapStore on PostgreSQL: the same tables and versioning as the SQLite store (maps, trees and
// observations whose rows carry the version range [valid_from, valid_to) they belong to,
// map_versions as the history), so that several forestmapd replicas can serve the same maps.
// Schema versioned in table forestmap_schema (storage/postgres/schema.cc). What a store does is
// VersionedMapStore's (storage/versioned_map_store.h); this backend gives it connections,
// statements and locks.

#include <cstdint>
#include <memory>
#include <string>

#include "storage/versioned_map_store.h"

namespace forestmap::storage {

class TokenBackend;  // storage/token_backend.h

struct PostgresMapStoreOptions {
  int max_connections = 8;  // connections to the server this store opens at most (count)

  // Throws StorageError(kInvalidArgument) for fewer than one connection.
  void Check() const;
};

// Thread-safety: every method may be called from many threads and many processes at once.
// Each call borrows one pooled connection. Reads run in one REPEATABLE READ READ ONLY
// transaction, so they see one committed version. Every write to a map (WriteTrees, Merge,
// RestoreVersion, DeleteMap) runs in one transaction that first takes the transaction-level
// advisory lock pg_advisory_xact_lock(map id): writes to one map serialize across all replicas
// (as the SQLite store serializes all writes), writes to different maps run in parallel, and
// what a merge reads is the version its changes apply to. Readers never wait for writers (MVCC).
// Doubles round-trip bit for bit (-0.0 too); attributes are JSON object text as in SQLite.
// An upload is staged in a TEMP table of the upload's own session and copied into trees at Commit
// under the map's advisory lock (storage/postgres/upload.cc).
class PostgresMapStore final : public VersionedMapStore {
 public:
  static constexpr int64_t kSchemaVersion = 7;
  // Trees or observation rows per INSERT ... SELECT FROM unnest(...) statement.
  static constexpr size_t kRowsPerInsert = 10000;

  // Connects to `conninfo` (a libpq URI or key=value string) and migrates the schema to
  // kSchemaVersion. Throws StorageError naming the server on failure.
  explicit PostgresMapStore(const std::string& conninfo,
                            const PostgresMapStoreOptions& options = {});
};

// Access tokens (storage/token_store.h) in the PostgreSQL database `conninfo` names, in a table
// made on first use (storage/postgres/tokens.cc). Throws StorageError.
std::unique_ptr<TokenBackend> OpenPostgresTokens(const std::string& conninfo);

}  // namespace forestmap::storage
