#include "storage/postgres/store.h"

#include <memory>
#include <string>

#include "storage/postgres/internal.h"

namespace forestmap::storage {

using Code = StorageError::Code;

void PostgresMapStoreOptions::Check() const {
  if (max_connections < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "PostgresMapStoreOptions: max_connections must be >= 1");
  }
}

namespace {

const PostgresMapStoreOptions& Checked(const PostgresMapStoreOptions& options) {
  options.Check();
  return options;
}

}  // namespace

PostgresMapStore::PostgresMapStore(const std::string& conninfo,
                                   const PostgresMapStoreOptions& options)
    : VersionedMapStore(std::make_unique<pg::Backend>(conninfo, options)) {}

namespace pg {

Backend::Backend(const std::string& conninfo, const PostgresMapStoreOptions& options)
    : conninfo_(conninfo),
      pool_([conninfo] { return std::make_unique<Connection>(conninfo); },
            Checked(options).max_connections,
            [](const Connection& conn) { return conn.healthy(); }) {
  if (static_cast<int64_t>(SchemaSteps().size()) != PostgresMapStore::kSchemaVersion) {
    throw StorageError(Code::kInternal, "schema steps and kSchemaVersion disagree");
  }
  pool_.With([](Connection& conn) { MigrateSchema(conn, SchemaSteps()); });
}

void Backend::WithReader(const Body& body) {
  pool_.With([&](Connection& conn) {
    Session session(conn);
    body(session);
  });
}

void Backend::WithWriter(const Body& body) { WithReader(body); }

}  // namespace pg
}  // namespace forestmap::storage
