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
  if (reserve_mib < 0) fail("reserve_mib must be >= 0 (0: none)");
}

SqliteMapStore::SqliteMapStore(const std::string& path, const SqliteMapStoreOptions& options)
    : VersionedMapStore(std::make_unique<sqlite::Backend>(path, options)) {}

namespace sqlite {

constexpr int64_t kBytesPerMib = 1 << 20;

Backend::Backend(const std::string& path, const SqliteMapStoreOptions& options) try
    : options_(options),
      reserve_(path + "-reserve", path == ":memory:" ? 0 : options.reserve_mib * kBytesPerMib) {
  options_.Check();
  if (path.empty()) {
    throw StorageError(Code::kInvalidArgument, "database path is empty (use ':memory:')");
  }
  if (sqlite3_threadsafe() == 0) {
    throw StorageError(Code::kInternal, "the linked SQLite library was built without threads");
  }
  // Opening a database in WAL mode writes (the -shm index, the start-up writes): on a full disk it
  // needs the reserved room, taken again once the database is open.
  if (path != ":memory:") reserve_.Release();
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
  OpenWrites(path);
  if (path == ":memory:") return;  // the database exists on this one connection only
  if (options_.reserve_mib > 0 && !reserve_.Hold()) {
    AddOpenWarning("no room for the " + std::to_string(options_.reserve_mib) +
                   " MiB reserved for deletes and prunes on a full disk (" + path +
                   "-reserve); it is taken after the next delete or prune, or start, that finds "
                   "the room");
  }
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

void Backend::AddOpenWarning(const std::string& warning) {
  open_warning_ += (open_warning_.empty() ? "" : "; ") + warning;
}

bool Backend::Checkpoint() {
  return sqlite3_wal_checkpoint_v2(writer_->handle(), nullptr, SQLITE_CHECKPOINT_TRUNCATE, nullptr,
                                   nullptr) == SQLITE_OK;
}

void Backend::WithRoom(const std::function<void()>& step) {
  // Room, first from the WAL (a checkpoint gives its file back to the file system), then from the
  // reserve (and the WAL once more: a checkpoint of new pages may need room in the file).
  enum class Next { kCheckpoint, kReserve, kNothing } next = Next::kCheckpoint;
  for (;;) {
    try {
      return step();
    } catch (const StorageError& e) {
      if (e.code() != Code::kFull) throw;
      if (next == Next::kCheckpoint) {
        next = Next::kReserve;
        if (Checkpoint()) continue;
      }
      if (next != Next::kReserve || !reserve_.Release()) throw;
      next = Next::kNothing;
      Checkpoint();
    }
  }
}

void Backend::OpenWrites(const std::string& path) {
  try {
    WithRoom([&] { MigrateSchema(*writer_, SchemaSteps()); });
  } catch (const StorageError& e) {
    if (e.code() != Code::kFull) throw;
    throw StorageError(Code::kFull, std::string("the schema migration of this version has no "
                                                "room; free disk space (or raise the size "
                                                "limit) and start again: ") +
                                        e.what());
  }
  const auto skip_when_full = [&](const char* step, const std::function<void()>& write) {
    try {
      WithRoom(write);
    } catch (const StorageError& e) {
      if (e.code() != Code::kFull) throw;
      if (!writer_->InAutocommit()) {
        sqlite3_exec(writer_->handle(), "ROLLBACK", nullptr, nullptr, nullptr);
      }
      AddOpenWarning(std::string("database full: ") + step +
                     " skipped; reads are served, and writes that need room fail until room is "
                     "freed (delete maps, prune history, or free disk space) [" +
                     e.what() + "]");
    }
  };
  skip_when_full("the removal of abandoned uploads", [&] { RemoveAbandonedUploads(*writer_); });
  if (path == ":memory:") return;
  writer_->EnableWal();  // writes only when the file is not in WAL mode yet
  skip_when_full("the write probe", [&] { RefuseReadOnlyDatabase(*writer_); });
}

void Backend::WithFreeingWriter(const Body& body) {
  std::lock_guard<std::mutex> lock(writer_mutex_);
  WithRoom([&] {
    Session session(*writer_);
    body(session);
  });
  if (!readers_) return;  // ":memory:": no WAL, no file system
  // The pages this write freed are reused by later writes, which append to the WAL first: the
  // WAL's file goes back to the file system for them, and the reserve is taken again from it
  // when there is room. Best effort.
  Checkpoint();
  reserve_.Hold();
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
