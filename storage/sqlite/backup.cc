#include "storage/backup.h"

#include <sqlite3.h>

#include <filesystem>
#include <system_error>

#include "storage/map_store.h"
#include "storage/sqlite/database.h"

namespace forestmap::storage {
namespace {

// Frees an sqlite3_backup on every path; Finish() reports its final result.
class Backup {
 public:
  Backup(sqlite::Database& destination, sqlite::Database& source)
      : destination_(destination),
        backup_(sqlite3_backup_init(destination.handle(), "main", source.handle(), "main")) {
    if (backup_ == nullptr) destination_.Fail(sqlite3_errcode(destination.handle()), "backup");
  }
  ~Backup() {
    if (backup_ != nullptr) sqlite3_backup_finish(backup_);
  }
  Backup(const Backup&) = delete;
  Backup& operator=(const Backup&) = delete;

  // Copies every page in one step: the source stays in one read transaction throughout.
  int64_t CopyAll() {
    const int result = sqlite3_backup_step(backup_, -1);
    const int64_t pages = sqlite3_backup_pagecount(backup_);
    const int finish = sqlite3_backup_finish(backup_);
    backup_ = nullptr;
    if (result != SQLITE_DONE) destination_.Fail(result, "backup step");
    if (finish != SQLITE_OK) destination_.Fail(finish, "backup finish");
    return pages;
  }

 private:
  sqlite::Database& destination_;
  sqlite3_backup* backup_;
};

}  // namespace

BackupResult BackupDatabase(const std::string& source_path, const std::string& out_path,
                            int busy_timeout_ms) {
  std::error_code error;
  if (std::filesystem::exists(out_path, error)) {
    throw StorageError(StorageError::Code::kAlreadyExists,
                       "backup target " + out_path + " exists; choose a new file");
  }
  if (!std::filesystem::is_regular_file(source_path, error)) {
    throw StorageError(StorageError::Code::kNotFound,
                       "database " + source_path + " does not exist or is not a file");
  }
  sqlite::Database source(source_path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, busy_timeout_ms);
  // Fails with "file is not a database" for something else, before the target is created.
  source.QueryInt64("PRAGMA user_version");
  BackupResult result;
  {
    sqlite::Database destination(out_path,
                                 SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
                                 busy_timeout_ms);
    result.pages = Backup(destination, source).CopyAll();
    sqlite::Statement check(destination, "PRAGMA quick_check");
    result.integrity = check.Step() ? check.ColumnText(0) : "no answer";
  }
  result.bytes = static_cast<int64_t>(std::filesystem::file_size(out_path, error));
  if (result.integrity != "ok") {
    throw StorageError(StorageError::Code::kInternal,
                       "backup " + out_path + " failed its check: " + result.integrity);
  }
  return result;
}

}  // namespace forestmap::storage
