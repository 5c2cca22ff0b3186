#pragma once
// MapStore on SQLite: one database file holds every map (tables maps, trees, observations,
// map_versions, and an R*Tree index over blocks of nearby trees), schema versioned with PRAGMA
// user_version (storage/sqlite/schema.cc). What a store does is VersionedMapStore's
// (storage/versioned_map_store.h); this backend gives it connections, statements and locks.

#include <cstdint>
#include <memory>
#include <string>

#include "storage/versioned_map_store.h"

namespace forestmap::storage {

class TokenBackend;  // storage/token_backend.h

struct SqliteMapStoreOptions {
  int busy_timeout_ms = 5000;  // ms a statement waits for a lock held by another process
  int max_readers = 4;         // reader connections of a file database (count), opened lazily
  int cache_mib = 64;          // MiB of page cache per connection (SQLite's default is 2)
  // MiB the database file may grow to (PRAGMA max_page_count; 0: no limit). A write that needs
  // more fails with kFull, like a full disk. A file already larger cannot grow further.
  int64_t max_db_mib = 0;
  // MiB of room kept on the database's file system in the file "<path>-reserve" (allocated
  // blocks; 0: none): when the disk is full, DeleteMap, PruneVersions and the writes of opening
  // the database give it back and use it, so a full disk can be freed and the store opened.
  // Reserved again after such a write, or at the next open, when the file system has the room.
  int64_t reserve_mib = 0;

  // Throws StorageError(kInvalidArgument) naming the field for a negative timeout, fewer than
  // one reader, a cache smaller than 1 MiB or a negative size limit or reserve.
  void Check() const;
};

// Thread-safety: every method may be called from many threads at once.
// - File database: one writer connection guarded by a mutex (writes are serialized), plus a pool
//   of up to `max_readers` reader connections. A read borrows one connection for the whole call
//   (waiting when all are busy) and reads inside one transaction, so it sees one committed
//   version; thanks to WAL, reads run in parallel with each other and with the writer.
// - ":memory:" database: an in-memory database lives on a single connection, so every call,
//   read or write, takes the one mutex (reads are serialized too). Meant for tests.
// Other processes may open the same file; SQLite's locks (with `busy_timeout_ms`) serialize them,
// and a lock still held after the timeout is reported as StorageError::Code::kUnavailable.
//
// Storage details: attributes are stored as JSON object text (NULL when empty). Doubles
// round-trip bit for bit, except that -0.0 reads back as +0.0 (SQLite's REAL affinity stores
// integral values as integers). The spatial index holds blocks of up to kTreesPerBlock trees
// that are close together, not single trees: one R*Tree insertion per tree would cost ~10 us, and
// a million-tree write several times longer than the rest of the write. A change never edits a
// row in place: it closes the current row (valid_to) and inserts the new state, so blocks keep
// their rowid ranges and old versions stay readable; queries filter by version.
// Merge runs its callback on the writer connection inside BEGIN IMMEDIATE, holding the writer
// mutex: merges (and all other writes) serialize, and readers keep reading the last committed
// version meanwhile (WAL). Pruning leaves free pages that later writes reuse; the file does not
// shrink (VACUUM). An upload is staged in table trees as pending rows (valid_to = -upload id) by
// short transactions; its Commit turns them current in one UPDATE (storage/sqlite/upload.cc).
class SqliteMapStore final : public VersionedMapStore {
 public:
  // Schema version this code writes; a database with a newer PRAGMA user_version is refused.
  static constexpr int64_t kSchemaVersion = 13;
  static constexpr size_t kTreesPerBlock = 32;

  // Opens (creating if missing) the database at `path` and migrates its schema to
  // kSchemaVersion. ":memory:" gives a private in-memory database. Throws StorageError;
  // kReadOnly, naming the cause, for a database this process cannot write (read-only file,
  // directory or file system): a server that could only fail its writes refuses to start. A full
  // disk (or size limit) opens all the same when only the removal of abandoned uploads or the
  // write probe found no room (OpenWarning() says so; writes then fail as kFull); a migration
  // without room throws kFull.
  explicit SqliteMapStore(const std::string& path, const SqliteMapStoreOptions& options = {});
};

// Access tokens (storage/token_store.h) in the SQLite file at `path` (table access_tokens of the
// map schema, migrated like SqliteMapStore does; storage/sqlite/tokens.cc). Throws StorageError.
std::unique_ptr<TokenBackend> OpenSqliteTokens(const std::string& path, int busy_timeout_ms);

}  // namespace forestmap::storage
