#pragma once
// The one checked wrapper around the sqlite3 C API: RAII connection, prepared statement and
// transaction. Every failing sqlite3 call throws StorageError with "<what>: <sqlite3_errmsg>".
// SQL text is always a constant of the caller; values go through bound parameters only.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "storage/map_store.h"

struct sqlite3;
struct sqlite3_stmt;

namespace forestmap::storage::sqlite {

// Error code for an (extended) sqlite3 result code: UNIQUE/PRIMARY KEY violations ->
// kAlreadyExists, other constraint violations -> kInvalidArgument, SQLITE_BUSY/LOCKED (another
// connection held the lock past the busy timeout: worth a retry) -> kUnavailable, SQLITE_FULL
// (disk full, or PRAGMA max_page_count reached) -> kFull, SQLITE_READONLY (any reason) ->
// kReadOnly, SQLITE_CORRUPT/NOTADB -> kCorrupt, else kInternal.
StorageError::Code CodeForResult(int extended_result_code);

// One connection. Not thread-safe: a connection is used by one thread at a time (the owner
// serializes), so owners open it with SQLITE_OPEN_NOMUTEX and skip SQLite's own locking.
class Database {
 public:
  // `flags`: SQLITE_OPEN_* bits. `busy_timeout_ms`: how long a statement waits for a lock held by
  // another connection before failing with SQLITE_BUSY.
  Database(const std::string& path, int flags, int busy_timeout_ms);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  // Runs constant SQL without parameters (DDL, PRAGMA, BEGIN/COMMIT); may hold several statements.
  void Execute(const char* sql);
  // Runs a constant single-row query, returns its first column as an integer (e.g. a PRAGMA).
  int64_t QueryInt64(const char* sql);
  // True when no transaction is open on this connection.
  bool InAutocommit() const;
  // Rowid of the last row this connection inserted.
  int64_t LastInsertRowId() const;
  // Rows changed by the last INSERT, UPDATE or DELETE of this connection.
  int64_t Changes() const;
  // Switches a file database to write-ahead logging (readers then run alongside a writer);
  // throws when the file system cannot do it.
  void EnableWal();

  sqlite3* handle() const { return db_; }
  const std::string& path() const { return path_; }

  // Throws StorageError for `result_code` with "<what>: <sqlite3_errmsg(db)>".
  [[noreturn]] void Fail(int result_code, std::string_view what) const;

 private:
  sqlite3* db_ = nullptr;
  std::string path_;
};

// Brings the schema to version steps.size() through PRAGMA user_version: steps[i] takes a database
// from version i to i + 1 and must end with "PRAGMA user_version = i + 1". Each step runs in its
// own write transaction, re-checking the version under the lock (another process may be migrating
// too). A database newer than steps.size() is refused before anything is touched.
void MigrateSchema(Database& db, const std::vector<const char*>& steps);

// One prepared statement. Parameter and column indices follow SQLite: parameters from 1,
// columns from 0.
class Statement {
 public:
  Statement(Database& db, const char* sql);
  // Prepares `sql` and binds `values` to ?1, ?2, ... in order: integers, doubles,
  // std::optional<double> (nullopt -> NULL) and text.
  template <typename... Values>
  Statement(Database& db, const char* sql, const Values&... values) : Statement(db, sql) {
    int index = 0;
    (Bind(++index, values), ...);
  }
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  void BindInt64(int index, int64_t value);
  void BindDouble(int index, double value);
  void BindOptionalDouble(int index, const std::optional<double>& value);  // nullopt -> NULL
  void BindText(int index, std::string_view value);  // copied by SQLite (SQLITE_TRANSIENT)
  void BindNull(int index);
  void BindBlob(int index, std::string_view bytes);  // copied by SQLite
  template <typename T>
  void Bind(int index, const T& value) {
    if constexpr (std::is_integral_v<T>) {
      BindInt64(index, value);
    } else if constexpr (std::is_floating_point_v<T>) {
      BindDouble(index, value);
    } else if constexpr (std::is_same_v<T, std::optional<double>>) {
      BindOptionalDouble(index, value);
    } else {
      BindText(index, value);
    }
  }

  // Advances: true when a row is available, false when the statement is done.
  bool Step();
  // Step() for a statement that returns no rows, then Reset(): the common "execute" case.
  void Run();
  // Rewinds for the next execution; bindings are kept. Never throws: after a failed Step(),
  // sqlite3_reset repeats that step's error, which Step() has already thrown.
  void Reset();

  bool ColumnIsNull(int column) const;
  int64_t ColumnInt64(int column) const;
  double ColumnDouble(int column) const;
  std::optional<double> ColumnOptionalDouble(int column) const;  // NULL -> nullopt
  std::string ColumnText(int column) const;                      // NULL -> ""
  std::string ColumnBlob(int column) const;                      // NULL -> ""
  // Steps once: the first column of the row, unset when there is none or it is NULL (MAX, MIN).
  std::optional<int64_t> OptionalInt64();

 private:
  void CheckBind(int result_code, int index);

  Database& db_;
  sqlite3_stmt* stmt_ = nullptr;
};

// A transaction on one connection: BEGIN IMMEDIATE for writes (takes the write lock up front, so
// a write never fails half-way on lock upgrade), BEGIN (deferred) for reads (the snapshot is
// fixed by the first read). Rolled back in the destructor unless Commit() ran.
class Transaction {
 public:
  enum class Kind { kRead, kWrite };
  Transaction(Database& db, Kind kind);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;

  void Commit();

 private:
  Database& db_;
  bool done_ = false;
};

}  // namespace forestmap::storage::sqlite
