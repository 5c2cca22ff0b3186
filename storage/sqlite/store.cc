#include "storage/sqlite/store.h"

#include <sqlite3.h>

#include <memory>
#include <mutex>
#include <string>

#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"

namespace forestmap::storage {

using Code = StorageError::Code;

void SqliteMapStoreOptions::Check() const {
  const auto fail = [](const std::string& message) {
    throw StorageError(Code::kInvalidArgument, "SqliteMapStoreOptions: " + message);
  };
  if (busy_timeout_ms < 0) fail("busy_timeout_ms must be >= 0");
  if (max_readers < 1) fail("max_readers must be >= 1");
  if (cache_mib < 1 || cache_mib > 1024 * 1024) fail("cache_mib must be in [1, 1048576]");
  if (max_db_mib < 0) fail("max_db_mib must be >= 0 (0: no limit)");
}

SqliteMapStore::SqliteMapStore(const std::string& path, const SqliteMapStoreOptions& options)
    : VersionedMapStore(std::make_unique<sqlite::Backend>(path, options)) {}

namespace sqlite {

Backend::Backend(const std::string& path, const SqliteMapStoreOptions& options) try
    : options_(options) {
  options_.Check();
  if (path.empty()) {
    throw StorageError(Code::kInvalidArgument, "database path is empty (use ':memory:')");
  }
  if (sqlite3_threadsafe() == 0) {
    throw StorageError(Code::kInternal, "the linked SQLite library was built without threads");
  }
  // NOMUTEX: each connection is used by one thread at a time (our mutex or the pool see to it).
  writer_ = std::make_unique<Database>(
      path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
      options_.busy_timeout_ms);
  ConfigureConnection(*writer_, options_, /*read_only=*/false);
  if (static_cast<int64_t>(SchemaSteps().size()) != SqliteMapStore::kSchemaVersion) {
    throw StorageError(Code::kInternal, "schema steps and kSchemaVersion disagree");
  }
  // Refuses a database of something else, and a newer schema, before any change.
  RefuseForeignDatabase(*writer_);
  MigrateSchema(*writer_, SchemaSteps());
  RemoveAbandonedUploads(*writer_);
  if (path == ":memory:") return;  // the database exists on this one connection only
  writer_->EnableWal();
  RefuseReadOnlyDatabase(*writer_);
  const SqliteMapStoreOptions reader_options = options_;
  readers_ = std::make_unique<ConnectionPool<Database>>(
      [path, reader_options] {
        auto reader = std::make_unique<Database>(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX,
                                                 reader_options.busy_timeout_ms);
        ConfigureConnection(*reader, reader_options, /*read_only=*/true);
        return reader;
      },
      options_.max_readers);
} catch (const StorageError& e) {
  // Any step that had to write (settings, migration, WAL, the probe) names the cause.
  if (e.code() == Code::kReadOnly) ThrowReadOnly(path, e.what());
}

void Backend::WithWriterDatabase(const std::function<void(Database&)>& body) {
  std::lock_guard<std::mutex> lock(writer_mutex_);
  body(*writer_);
}

void Backend::WithWriter(const Body& body) {
  WithWriterDatabase([&](Database& db) {
    Session session(db);
    body(session);
  });
}

void Backend::WithReader(const Body& body) {
  if (!readers_) return WithWriter(body);
  readers_->With([&](Database& db) {
    Session session(db);
    body(session);
  });
}

}  // namespace sqlite
}  // namespace forestmap::storage
