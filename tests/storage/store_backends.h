#pragma once
// The storage tests run against every MapStore backend: SQLite (in memory) and PostgreSQL (a
// fresh database on the throwaway test cluster of tests/pg_fixture.h, dropped after the test).
// Use with TEST_P and INSTANTIATE_TEST_SUITE_P(Backends, Fixture, kAllBackends, BackendName).

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "storage/postgres/store.h"
#include "storage/sqlite/store.h"
#include "tests/pg_fixture.h"

namespace forestmap::storage {

enum class Backend { kSqlite, kPostgres };

inline const auto kAllBackends = ::testing::Values(Backend::kSqlite, Backend::kPostgres);

inline std::string BackendName(const ::testing::TestParamInfo<Backend>& info) {
  return info.param == Backend::kSqlite ? "sqlite" : "postgresql";
}

// A store of `backend` for one test; the PostgreSQL database goes away with it.
class TestStore {
 public:
  explicit TestStore(Backend backend) {
    if (backend == Backend::kSqlite) {
      store_ = std::make_unique<SqliteMapStore>(":memory:");
    } else {
      database_ = std::make_unique<testing::TestDatabase>();
      store_ = std::make_unique<PostgresMapStore>(database_->url());
    }
  }
  ~TestStore() { store_.reset(); }  // before the database is dropped
  MapStore& operator*() { return *store_; }
  // A second store on the same database (another process / replica); SQLite: not available.
  std::unique_ptr<MapStore> Another() const {
    return database_ ? std::make_unique<PostgresMapStore>(database_->url()) : nullptr;
  }

 private:
  std::unique_ptr<testing::TestDatabase> database_;
  std::unique_ptr<MapStore> store_;
};

}  // namespace forestmap::storage
