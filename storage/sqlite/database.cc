#include "storage/sqlite/database.h"

#include <sqlite3.h>

#include <string>

namespace forestmap::storage::sqlite {
namespace {

// Statement text in error messages, cut so a message stays one readable line.
std::string Abbreviate(const char* sql) {
  constexpr size_t kMaxChars = 80;
  std::string text = sql ? sql : "";
  for (char& c : text) {
    if (c == '\n') c = ' ';
  }
  if (text.size() > kMaxChars) text = text.substr(0, kMaxChars) + "...";
  return "'" + text + "'";
}

}  // namespace

StorageError::Code CodeForResult(int extended_result_code) {
  switch (extended_result_code) {
    case SQLITE_CONSTRAINT_UNIQUE:
    case SQLITE_CONSTRAINT_PRIMARYKEY:
      return StorageError::Code::kAlreadyExists;
    default:
      break;
  }
  switch (extended_result_code & 0xff) {
    case SQLITE_CONSTRAINT:
      return StorageError::Code::kInvalidArgument;
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return StorageError::Code::kUnavailable;
    case SQLITE_FULL:  // also ENOSPC: the unix VFS reports a failed write for no space as FULL
      return StorageError::Code::kFull;
    case SQLITE_READONLY:
      return StorageError::Code::kReadOnly;
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return StorageError::Code::kCorrupt;
    default:
      return StorageError::Code::kInternal;
  }
}

// ---- Database ----

Database::Database(const std::string& path, int flags, int busy_timeout_ms) : path_(path) {
  const int rc = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
  if (rc != SQLITE_OK) {
    // On most failures SQLite still returns a handle that carries the message; free it after.
    const std::string message =
        "open database '" + path + "': " + (db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc));
    sqlite3_close_v2(db_);
    db_ = nullptr;
    throw StorageError(CodeForResult(rc), message);
  }
  sqlite3_extended_result_codes(db_, 1);
  const int timeout_rc = sqlite3_busy_timeout(db_, busy_timeout_ms);
  if (timeout_rc != SQLITE_OK) {
    const std::string message = "set busy timeout on '" + path + "': " + sqlite3_errmsg(db_);
    sqlite3_close_v2(db_);
    db_ = nullptr;
    throw StorageError(StorageError::Code::kInternal, message);
  }
}

Database::~Database() {
  // close_v2 defers the close until every statement is finalized; the RAII statements that
  // reference this connection are always destroyed first, so this closes immediately.
  sqlite3_close_v2(db_);
}

void Database::Fail(int result_code, std::string_view what) const {
  // The connection's last error normally describes `result_code` (with the extended code and a
  // precise message); when it does not, fall back to the generic text of `result_code`.
  int code = sqlite3_extended_errcode(db_);
  std::string message = sqlite3_errmsg(db_);
  if ((code & 0xff) != (result_code & 0xff)) {
    code = result_code;
    message = sqlite3_errstr(result_code);
  }
  throw StorageError(CodeForResult(code),
                     std::string(what) + ": " + message + " (database '" + path_ + "')");
}

void Database::Execute(const char* sql) {
  const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) Fail(rc, "execute " + Abbreviate(sql));
}

int64_t Database::QueryInt64(const char* sql) {
  Statement statement(*this, sql);
  if (!statement.Step()) {
    throw StorageError(StorageError::Code::kInternal,
                       "query " + Abbreviate(sql) + " returned no row (database '" + path_ + "')");
  }
  return statement.ColumnInt64(0);
}

bool Database::InAutocommit() const { return sqlite3_get_autocommit(db_) != 0; }

int64_t Database::LastInsertRowId() const { return sqlite3_last_insert_rowid(db_); }

int64_t Database::Changes() const { return sqlite3_changes64(db_); }

void Database::EnableWal() {
  Statement statement(*this, "PRAGMA journal_mode = WAL");
  const std::string mode = statement.Step() ? statement.ColumnText(0) : "";
  if (mode != "wal") {
    throw StorageError(StorageError::Code::kInternal,
                       "database '" + path_ +
                           "' cannot use write-ahead logging (journal mode "
                           "stays '" +
                           mode + "'); is it on a network file system?");
  }
}

void MigrateSchema(Database& db, const std::vector<const char*>& steps) {
  const auto latest = static_cast<int64_t>(steps.size());
  const int64_t found = db.QueryInt64("PRAGMA user_version");
  if (found > latest) {
    throw StorageError(StorageError::Code::kInternal,
                       "database '" + db.path() + "' has schema version " + std::to_string(found) +
                           ", newer than version " + std::to_string(latest) +
                           " that this program knows; use a newer forestmap build");
  }
  for (int64_t target = found + 1; target <= latest; ++target) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    if (db.QueryInt64("PRAGMA user_version") >= target) continue;  // done by another process
    db.Execute(steps[static_cast<size_t>(target - 1)]);
    if (db.QueryInt64("PRAGMA user_version") != target) {
      throw StorageError(StorageError::Code::kInternal, "schema migration step to version " +
                                                            std::to_string(target) +
                                                            " did not set PRAGMA user_version");
    }
    transaction.Commit();
  }
}

// ---- Statement ----

Statement::Statement(Database& db, const char* sql) : db_(db) {
  const int rc = sqlite3_prepare_v2(db.handle(), sql, -1, &stmt_, nullptr);
  if (rc != SQLITE_OK) db.Fail(rc, "prepare " + Abbreviate(sql));
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

void Statement::CheckBind(int result_code, int index) {
  if (result_code != SQLITE_OK) {
    db_.Fail(result_code,
             "bind parameter " + std::to_string(index) + " of " + Abbreviate(sqlite3_sql(stmt_)));
  }
}

void Statement::BindInt64(int index, int64_t value) {
  CheckBind(sqlite3_bind_int64(stmt_, index, value), index);
}

void Statement::BindDouble(int index, double value) {
  CheckBind(sqlite3_bind_double(stmt_, index, value), index);
}

void Statement::BindOptionalDouble(int index, const std::optional<double>& value) {
  if (value) {
    BindDouble(index, *value);
  } else {
    BindNull(index);
  }
}

void Statement::BindText(int index, std::string_view value) {
  CheckBind(
      sqlite3_bind_text64(stmt_, index, value.data(), value.size(), SQLITE_TRANSIENT, SQLITE_UTF8),
      index);
}

void Statement::BindNull(int index) { CheckBind(sqlite3_bind_null(stmt_, index), index); }

void Statement::BindBlob(int index, std::string_view bytes) {
  CheckBind(sqlite3_bind_blob64(stmt_, index, bytes.data(), bytes.size(), SQLITE_TRANSIENT), index);
}

std::string Statement::ColumnBlob(int column) const {
  if (ColumnIsNull(column)) return {};
  const void* bytes = sqlite3_column_blob(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  if (bytes == nullptr) return {};  // an empty blob
  return std::string(static_cast<const char*>(bytes), static_cast<size_t>(size));
}

bool Statement::Step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  db_.Fail(rc, "step " + Abbreviate(sqlite3_sql(stmt_)));
}

void Statement::Run() {
  Step();
  Reset();
}

void Statement::Reset() { sqlite3_reset(stmt_); }

std::optional<int64_t> Statement::OptionalInt64() {
  if (!Step() || ColumnIsNull(0)) return std::nullopt;
  return ColumnInt64(0);
}

bool Statement::ColumnIsNull(int column) const {
  return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}

int64_t Statement::ColumnInt64(int column) const { return sqlite3_column_int64(stmt_, column); }

double Statement::ColumnDouble(int column) const { return sqlite3_column_double(stmt_, column); }

std::optional<double> Statement::ColumnOptionalDouble(int column) const {
  if (ColumnIsNull(column)) return std::nullopt;
  return ColumnDouble(column);
}

std::string Statement::ColumnText(int column) const {
  if (ColumnIsNull(column)) return {};
  const unsigned char* text = sqlite3_column_text(stmt_, column);
  if (text == nullptr) db_.Fail(SQLITE_NOMEM, "read text column");  // conversion ran out of memory
  const int bytes = sqlite3_column_bytes(stmt_, column);
  return std::string(reinterpret_cast<const char*>(text), static_cast<size_t>(bytes));
}

// ---- Transaction ----

Transaction::Transaction(Database& db, Kind kind) : db_(db) {
  db_.Execute(kind == Kind::kWrite ? "BEGIN IMMEDIATE" : "BEGIN");
}

Transaction::~Transaction() {
  if (done_ || db_.InAutocommit()) return;  // committed, or SQLite already rolled back
  // Cannot throw from a destructor; a failed ROLLBACK leaves nothing more we could do here.
  sqlite3_exec(db_.handle(), "ROLLBACK", nullptr, nullptr, nullptr);
}

void Transaction::Commit() {
  db_.Execute("COMMIT");
  done_ = true;
}

}  // namespace forestmap::storage::sqlite
