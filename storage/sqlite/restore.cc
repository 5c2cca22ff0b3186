// SqliteMapStore::RestoreVersion: a new version whose trees and observation rows are those of an
// older one. Rows valid at that version but no longer current come back as copies; current rows
// the version did not have are closed; rows valid at both simply stay.

#include <sqlite3.h>

#include <set>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"
#include "storage/sqlite/store.h"
#include "storage/store_steps.h"

namespace forestmap::storage {
namespace {

using internal::MapRow;
using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;

// Tree rows: copies of those valid at `version` and no longer current, current rows newer than
// it closed at `next`; counts into `record`.
void RestoreTreeRows(Database& db, const MapRow& map, int64_t version, int64_t next,
                     VersionRecord& record) {
  std::vector<TreeRecord> copies;
  {
    Statement select(db, "SELECT " FORESTMAP_TREE_COLUMNS
                         " FROM trees AS t INDEXED BY "
                         "trees_history WHERE t.map_id = ?1 AND t.valid_to != " FORESTMAP_CURRENT
                         " AND t.valid_from <= ?2 AND t.valid_to > ?2");
    select.BindInt64(1, map.id);
    select.BindInt64(2, version);
    while (select.Step()) copies.push_back(internal::ReadTreeRow(select, map.info.name));
  }
  std::set<int64_t> closed;
  {
    Statement close(db,
                    "UPDATE trees SET valid_to = ?3 WHERE map_id = ?1 AND valid_from > ?2 AND "
                    "valid_to = " FORESTMAP_CURRENT " RETURNING tree_id");
    close.BindInt64(1, map.id);
    close.BindInt64(2, version);
    close.BindInt64(3, next);
    while (close.Step()) closed.insert(close.ColumnInt64(0));
  }
  std::vector<int64_t> ids;
  for (const TreeRecord& tree : copies) {
    ids.push_back(*tree.id);
    ++(closed.count(*tree.id) ? record.trees_updated : record.trees_added);
  }
  record.trees_removed = static_cast<int64_t>(closed.size()) - record.trees_updated;
  internal::InsertTrees(db, map, copies, ids, next);
}

// Observation rows, the same way.
void RestoreObservationRows(Database& db, const MapRow& map, int64_t version, int64_t next,
                            VersionRecord& record) {
  std::vector<ObservationRecord> copies;
  {
    Statement select(
        db,
        "SELECT " FORESTMAP_OBSERVATION_COLUMNS
        " FROM observations AS o "
        "INDEXED BY observations_history WHERE o.map_id = ?1 AND o.valid_to != " FORESTMAP_CURRENT
        " AND o.valid_from <= ?2 AND o.valid_to > ?2 ORDER BY o.id");
    select.BindInt64(1, map.id);
    select.BindInt64(2, version);
    while (select.Step()) copies.push_back(internal::ReadObservationRow(select));
  }
  Statement close(db,
                  "UPDATE observations SET valid_to = ?3 WHERE map_id = ?1 AND "
                  "valid_from > ?2 AND valid_to = " FORESTMAP_CURRENT);
  close.BindInt64(1, map.id);
  close.BindInt64(2, version);
  close.BindInt64(3, next);
  close.Run();
  record.observations_removed = sqlite3_changes64(db.handle());
  internal::InsertObservations(db, map.id, copies, next);
  record.observations_added = static_cast<int64_t>(copies.size());
}

}  // namespace

MapInfo SqliteMapStore::RestoreVersion(const std::string& name, int64_t version) {
  internal::CheckName(name);
  MapInfo result;
  WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    MapRow map = internal::RequireMap(db, name);
    const VersionRecord old = internal::RequireVersion(db, map, version);
    const int64_t next = map.info.version + 1;
    VersionRecord record;
    RestoreTreeRows(db, map, version, next, record);
    RestoreObservationRows(db, map, version, next, record);

    internal::StampRestore(map.info, record, old, internal::ScanExtent(db, map.id));
    internal::UpdateMapRow(db, map);
    internal::InsertVersion(db, map.id, record);
    internal::CommitWrite(db, transaction, map.info);
    result = map.info;
  });
  return result;
}

}  // namespace forestmap::storage
