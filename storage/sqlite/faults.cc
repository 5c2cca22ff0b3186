// Faults of a SQLite database found when it is opened: a database this process cannot write is
// refused with its cause, and the size limit of --max-db-mb.

#include <sqlite3.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include "storage/sqlite/internal.h"

namespace forestmap::storage::sqlite {
namespace {

constexpr int64_t kBytesPerMib = 1 << 20;

// Why `path` cannot be written, as far as the file system tells.
std::string ReadOnlyCause(const std::string& path) {
  const std::filesystem::path file = std::filesystem::absolute(path);
  const std::string dir = file.parent_path().string();
  struct statvfs fs {};
  if (statvfs(dir.c_str(), &fs) == 0 && (fs.f_flag & ST_RDONLY) != 0) {
    return "its file system is mounted read-only";
  }
  if (access(file.c_str(), W_OK) != 0) return "the file is not writable by this user";
  if (access(dir.c_str(), W_OK) != 0) {
    return "its directory " + dir +
           " is not writable by this user (SQLite needs it for the -wal "
           "and -shm files)";
  }
  return "the file cannot be written";
}

}  // namespace

void ThrowReadOnly(const std::string& path, const std::string& detail) {
  throw StorageError(StorageError::Code::kReadOnly,
                     "database '" + path + "' is read-only: " + ReadOnlyCause(path) + " (uid " +
                         std::to_string(geteuid()) +
                         "). forestmapd writes its database: make the "
                         "file and its directory writable for this user, or give --db a "
                         "writable copy [" +
                         detail + "]");
}

void RefuseReadOnlyDatabase(Database& db) {
  if (sqlite3_db_readonly(db.handle(), "main") == 1) {
    throw StorageError(StorageError::Code::kReadOnly, "opened read-only by the operating system");
  }
  // Opened for writing does not mean writable (a read-only directory, a file system that fails
  // writes): commit one real write, the schema version rewritten with its own value. A failure
  // is thrown as it is (the caller names the cause for kReadOnly).
  const std::string probe = "BEGIN IMMEDIATE; PRAGMA user_version = " +
                            std::to_string(db.QueryInt64("PRAGMA user_version")) + "; COMMIT";
  try {
    db.Execute(probe.c_str());
  } catch (const StorageError&) {
    if (!db.InAutocommit()) sqlite3_exec(db.handle(), "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

void LimitDatabaseSize(Database& db, int64_t max_mib) {
  if (max_mib <= 0) return;
  const int64_t page_bytes = db.QueryInt64("PRAGMA page_size");
  const int64_t pages = std::max<int64_t>(1, max_mib * kBytesPerMib / page_bytes);
  // PRAGMA values cannot be bound; this one is an integer from checked options.
  const std::string sql = "PRAGMA max_page_count = " + std::to_string(pages);
  db.QueryInt64(sql.c_str());  // returns the limit in force (never below the current size)
}

}  // namespace forestmap::storage::sqlite
