#pragma once
// The storage tests run against every MapStore backend: SQLite in memory, SQLite on a file (for
// what needs a second connection: reader pools, replicas, raw queries) and PostgreSQL (a fresh
// database on the throwaway test cluster of tests/pg_fixture.h, dropped after the test).
// Use with TEST_P and INSTANTIATE_TEST_SUITE_P(Backends, Fixture, kAllBackends, BackendName).

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <memory>
#include <string>
#include <vector>

#include "storage/postgres/connection.h"
#include "storage/postgres/store.h"
#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "tests/pg_fixture.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {

enum class Backend { kSqlite, kSqliteFile, kPostgres };

// The shared suite: every database kind a MapStore runs on.
inline const auto kAllBackends = ::testing::Values(Backend::kSqlite, Backend::kPostgres);
// Databases a second connection (another store, a raw query) can open.
inline const auto kSharedBackends = ::testing::Values(Backend::kSqliteFile, Backend::kPostgres);

inline std::string BackendName(const ::testing::TestParamInfo<Backend>& info) {
  switch (info.param) {
    case Backend::kSqlite:
      return "sqlite";
    case Backend::kSqliteFile:
      return "sqlite_file";
    case Backend::kPostgres:
      return "postgresql";
  }
  return "unknown";
}

// A store of `backend` for one test; its database goes away with it.
class TestStore {
 public:
  explicit TestStore(Backend backend) : backend_(backend) {
    switch (backend) {
      case Backend::kSqlite:
        db_ = ":memory:";
        break;
      case Backend::kSqliteFile:
        directory_ = std::make_unique<TestDirectory>();
        db_ = directory_->File("maps.db");
        break;
      case Backend::kPostgres:
        database_ = std::make_unique<testing::TestDatabase>();
        db_ = database_->url();
        break;
    }
    store_ = Open();
  }
  ~TestStore() { store_.reset(); }  // before the database is dropped
  MapStore& operator*() { return *store_; }
  // The `--db` value of the database: ":memory:", a file path or a postgresql:// URL.
  const std::string& db() const { return db_; }
  // A second store on the same database (another process / replica); in memory: not available.
  std::unique_ptr<MapStore> Another() const {
    return backend_ == Backend::kSqlite ? nullptr : Open();
  }
  // The first column of every row of `sql`, as text, read by a connection of its own (not for
  // the in-memory database).
  std::vector<std::string> Column(const char* sql) const {
    std::vector<std::string> values;
    if (backend_ == Backend::kPostgres) {
      pg::Connection conn(db_);
      const pg::Result rows = conn.Exec(sql);
      for (int r = 0; r < rows.rows(); ++r) values.push_back(rows.Text(r, 0));
    } else {
      sqlite::Database db(db_, SQLITE_OPEN_READONLY, 1000);
      sqlite::Statement rows(db, sql);
      while (rows.Step()) values.push_back(rows.ColumnText(0));
    }
    return values;
  }

 private:
  // On a file, fewer readers than the concurrency tests' reading threads: they wait for the pool.
  std::unique_ptr<MapStore> Open() const {
    if (backend_ == Backend::kPostgres) return std::make_unique<PostgresMapStore>(db_);
    return std::make_unique<SqliteMapStore>(db_, SqliteMapStoreOptions{.max_readers = 2});
  }

  Backend backend_;
  std::unique_ptr<TestDirectory> directory_;
  std::unique_ptr<testing::TestDatabase> database_;
  std::string db_;
  std::unique_ptr<MapStore> store_;
};

}  // namespace forestmap::storage
