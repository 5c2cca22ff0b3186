#pragma once
// A consistent copy of a live SQLite database, made with SQLite's online backup API while other
// connections and processes keep writing (forestmapd backup).

#include <cstdint>
#include <string>

namespace forestmap::storage {

struct BackupResult {
  int64_t pages = 0;      // pages copied
  int64_t bytes = 0;      // size of the copy, bytes
  std::string integrity;  // PRAGMA quick_check of the copy: "ok" when sound
};

// Copies the database at `source_path` to `out_path` in one read transaction of the source: the
// copy holds exactly one committed state (every version complete), whatever writers do meanwhile
// (with WAL they go on; without it they wait for the copy). Refuses an existing `out_path` and a
// source that is not a database. The copy is checked with PRAGMA quick_check before returning.
// Throws StorageError naming the file and the cause. `busy_timeout_ms`: how long to wait for a
// lock another connection holds.
BackupResult BackupDatabase(const std::string& source_path, const std::string& out_path,
                            int busy_timeout_ms = 5000);

}  // namespace forestmap::storage
