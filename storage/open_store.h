#pragma once
// The one door to storage for the server and the tools: the `--db` value names the database, and
// these functions open the store of its kind. Nothing outside storage/ needs to know the
// backends (storage/sqlite/, storage/postgres/); only this factory includes them.

#include <cstdint>
#include <memory>
#include <string>

#include "storage/map_store.h"

namespace forestmap::storage {

// True for a `--db` value that names a PostgreSQL server (postgresql:// or postgres:// URI).
bool IsPostgresUri(const std::string& db);

// What a log may show of a `--db` value: the path, or for a PostgreSQL URI "postgresql
// host:port/db" (never the user or password it may hold).
std::string DescribeDatabase(const std::string& db);

// Opens the store a `--db` value names: PostgresMapStore for a postgresql:// URI, else
// SqliteMapStore on the file path (":memory:" too), limited to `max_db_mib` MiB (0: no limit;
// SQLite only, kInvalidArgument for PostgreSQL), keeping kServerReserveMib MiB of room reserved
// for deletes, prunes and a start on a full disk (SqliteMapStoreOptions::reserve_mib). Throws
// StorageError.
inline constexpr int64_t kServerReserveMib = 64;
std::unique_ptr<MapStore> OpenMapStore(const std::string& db, int64_t max_db_mib = 0);

}  // namespace forestmap::storage
