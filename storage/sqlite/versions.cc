// SqliteMapStore: versions of shared maps (reading an old version, history) and the merge
// transaction; restoring a version is in sqlite_restore.cc.

#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <utility>

#include "storage/checks.h"
#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"
#include "storage/sqlite/store.h"
#include "storage/store_steps.h"

namespace forestmap::storage {
namespace {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;
using Code = StorageError::Code;
using internal::MapRow;

VersionRecord RequireVersionImpl(Database& db, const MapRow& map, int64_t version) {
  Statement select(db,
                   "SELECT version, created_unix_ms, kind, source, tree_count, confirmed_count, "
                   "trees_added, trees_updated, trees_removed, observations_added, "
                   "observations_removed, restored_from FROM map_versions WHERE map_id = ?1 AND "
                   "version = ?2");
  select.BindInt64(1, map.id);
  select.BindInt64(2, version);
  if (!select.Step()) {
    Statement first(db, "SELECT MIN(version) FROM map_versions WHERE map_id = ?1");
    first.BindInt64(1, map.id);
    const int64_t oldest = first.Step() ? first.ColumnInt64(0) : map.info.version;
    throw StorageError(Code::kNotFound, "map '" + map.info.name + "' has no version " +
                                            std::to_string(version) + "; versions " +
                                            std::to_string(oldest) + " to " +
                                            std::to_string(map.info.version) + " can be read");
  }
  VersionRecord r;
  r.version = select.ColumnInt64(0);
  r.created_unix_ms = select.ColumnInt64(1);
  r.kind = static_cast<VersionKind>(select.ColumnInt64(2));
  r.source = select.ColumnText(3);
  r.tree_count = select.ColumnInt64(4);
  r.confirmed_count = select.ColumnInt64(5);
  r.trees_added = select.ColumnInt64(6);
  r.trees_updated = select.ColumnInt64(7);
  r.trees_removed = select.ColumnInt64(8);
  r.observations_added = select.ColumnInt64(9);
  r.observations_removed = select.ColumnInt64(10);
  r.restored_from = select.ColumnInt64(11);
  return r;
}

std::vector<TreeRecord> TreesAtVersion(Database& db, const MapRow& map, int64_t version) {
  std::vector<TreeRecord> trees;
  if (version == map.info.version) {
    trees.reserve(static_cast<size_t>(map.info.tree_count));
    Statement select(db, "SELECT " FORESTMAP_TREE_COLUMNS
                         " FROM trees AS t INDEXED BY trees_current "
                         "WHERE t.map_id = ?1 AND t.valid_to = " FORESTMAP_CURRENT
                         " ORDER BY t.tree_id");
    select.BindInt64(1, map.id);
    while (select.Step()) trees.push_back(internal::ReadTreeRow(select, map.info.name));
    return trees;
  }
  // Rows of `version` that are still current, and closed rows that were valid then.
  Statement select(db, "SELECT " FORESTMAP_TREE_COLUMNS
                       " FROM trees AS t INDEXED BY trees_current "
                       "WHERE t.map_id = ?1 AND t.valid_to = " FORESTMAP_CURRENT
                       " AND t.valid_from <= ?2 UNION ALL SELECT " FORESTMAP_TREE_COLUMNS
                       " FROM trees AS t INDEXED BY trees_history WHERE t.map_id = ?1 AND "
                       "t.valid_to != " FORESTMAP_CURRENT
                       " AND t.valid_from <= ?2 AND "
                       "t.valid_to > ?2 ORDER BY 1");
  select.BindInt64(1, map.id);
  select.BindInt64(2, version);
  while (select.Step()) trees.push_back(internal::ReadTreeRow(select, map.info.name));
  return trees;
}

// Read access of a merge: the writer connection inside its write transaction.
class SqliteMergeReader final : public MergeReader {
 public:
  SqliteMergeReader(Database& db, const MapRow& map) : db_(db), map_(map) {}

  const MapInfo& map() const override { return map_.info; }

  std::vector<TreeRecord> TreesInBox(const Extent& box) override {
    internal::CheckBox(map_.info.name, box);
    return internal::CurrentTreesInBox(db_, map_, box);
  }

  std::vector<TreeRecord> TreesById(std::span<const int64_t> ids) override {
    Statement select(db_,
                     "SELECT " FORESTMAP_TREE_COLUMNS
                     " FROM trees AS t INDEXED BY trees_current "
                     "WHERE t.map_id = ?1 AND t.tree_id = ?2 AND t.valid_to = " FORESTMAP_CURRENT);
    select.BindInt64(1, map_.id);
    std::vector<TreeRecord> trees;
    for (const int64_t id : std::set<int64_t>(ids.begin(), ids.end())) {
      select.BindInt64(2, id);
      if (select.Step()) trees.push_back(internal::ReadTreeRow(select, map_.info.name));
      select.Reset();
    }
    return trees;
  }

  std::vector<ObservationRecord> ObservationsOfTrees(std::span<const int64_t> ids) override {
    Statement select(db_, "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                          " FROM observations AS o WHERE "
                          "o.map_id = ?1 AND o.tree_id = ?2 AND o.valid_to = " FORESTMAP_CURRENT);
    select.BindInt64(1, map_.id);
    std::vector<ObservationRecord> rows;
    for (const int64_t id : std::set<int64_t>(ids.begin(), ids.end())) {
      select.BindInt64(2, id);
      while (select.Step()) rows.push_back(internal::ReadObservationRow(select));
      select.Reset();
    }
    std::sort(rows.begin(), rows.end(),
              [](const ObservationRecord& a, const ObservationRecord& b) { return a.id < b.id; });
    return rows;
  }

  std::vector<ObservationRecord> ObservationsInCells(
      std::span<const ObservationCell> cells) override {
    Statement select(db_, "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                          " FROM observations AS o INDEXED BY observations_in_cell WHERE "
                          "o.map_id = ?1 AND o.cell_x = ?2 AND o.cell_y = ?3 AND "
                          "o.valid_to = " FORESTMAP_CURRENT);
    select.BindInt64(1, map_.id);
    std::vector<ObservationRecord> rows;
    for (const ObservationCell& cell : std::set<ObservationCell>(cells.begin(), cells.end())) {
      select.BindInt64(2, cell.x);
      select.BindInt64(3, cell.y);
      while (select.Step()) rows.push_back(internal::ReadObservationRow(select));
      select.Reset();
    }
    std::sort(rows.begin(), rows.end(),
              [](const ObservationRecord& a, const ObservationRecord& b) { return a.id < b.id; });
    return rows;
  }

  std::vector<ObservationRecord> ObservationsOfSource(const std::string& source) override {
    Statement select(db_, "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                          " FROM observations AS o WHERE "
                          "o.map_id = ?1 AND o.source = ?2 AND o.valid_to = " FORESTMAP_CURRENT
                          " ORDER BY o.id");
    select.BindInt64(1, map_.id);
    select.BindText(2, source);
    std::vector<ObservationRecord> rows;
    while (select.Step()) rows.push_back(internal::ReadObservationRow(select));
    return rows;
  }

  int64_t NextFreeTreeId() override {
    // Both partial indexes answer MAX directly; together they cover every row.
    Statement select(db_,
                     "SELECT MAX(m) FROM (SELECT MAX(tree_id) AS m FROM trees INDEXED BY "
                     "trees_current WHERE map_id = ?1 AND valid_to = " FORESTMAP_CURRENT
                     " UNION ALL SELECT MAX(tree_id) FROM trees INDEXED BY trees_history WHERE "
                     "map_id = ?1 AND valid_to != " FORESTMAP_CURRENT ")");
    select.BindInt64(1, map_.id);
    if (!select.Step() || select.ColumnIsNull(0)) return 1;
    const int64_t max_id = select.ColumnInt64(0);
    if (max_id == std::numeric_limits<int64_t>::max()) {
      throw StorageError(Code::kInvalidArgument,
                         "map '" + map_.info.name + "': no free tree ids left for new trees");
    }
    return std::max<int64_t>(max_id + 1, 1);
  }

 private:
  Database& db_;
  const MapRow& map_;
};

// What a change set did to the counts of the map (filled while applying it).
struct Tally {
  bool boundary_touched = false;  // a closed row lay on the extent's border: rescan the extent
};

// Closes the current row of tree `id` at `version`; returns whether there was one and adjusts
// the map's counts for the row that left.
bool CloseTree(Statement& close, MapRow& map, int64_t id, Tally& tally) {
  close.BindInt64(2, id);
  if (!close.Step()) {
    close.Reset();
    return false;
  }
  const bool confirmed = close.ColumnInt64(0) != 0;
  const double x = close.ColumnDouble(1), y = close.ColumnDouble(2);
  close.Reset();
  MapInfo& info = map.info;
  info.tree_count -= 1;
  info.confirmed_count -= confirmed ? 1 : 0;
  if (internal::OnBorder(info.extent, x, y)) tally.boundary_touched = true;
  return true;
}

// Writes `changes` as version map.version + 1 and updates `map` (row and info).
VersionRecord ApplyChanges(Database& db, MapRow& map, const MergeNote& note,
                           const MapChanges& changes) {
  internal::CheckPutTrees(map.info.name, changes);
  VersionRecord record = internal::NextVersion(map.info, note.kind, note.source);
  Tally tally;
  Statement close(db,
                  "UPDATE trees SET valid_to = ?3 WHERE map_id = ?1 AND tree_id = ?2 AND "
                  "valid_to = " FORESTMAP_CURRENT " RETURNING status, x, y");
  close.BindInt64(1, map.id);
  close.BindInt64(3, record.version);
  for (const int64_t id : changes.removed_trees) {
    if (!CloseTree(close, map, id, tally)) throw internal::TreeToRemoveMissing(map.info.name, id);
    ++record.trees_removed;
  }
  for (const TreeRecord& tree : changes.put_trees) {
    ++(CloseTree(close, map, *tree.id, tally) ? record.trees_updated : record.trees_added);
  }
  const internal::PutTrees put = internal::CountPutTrees(map.info, changes.put_trees);
  internal::InsertTrees(db, map, changes.put_trees, put.ids, record.version);

  Statement close_observation(db,
                              "UPDATE observations SET valid_to = ?3 WHERE id = ?2 AND "
                              "map_id = ?1 AND valid_to = " FORESTMAP_CURRENT);
  close_observation.BindInt64(1, map.id);
  close_observation.BindInt64(3, record.version);
  for (const int64_t id : changes.removed_observations) {
    close_observation.BindInt64(2, id);
    close_observation.Run();
    if (sqlite3_changes64(db.handle()) != 1) {
      throw internal::ObservationToRemoveMissing(map.info.name, id);
    }
  }
  internal::InsertObservations(db, map.id, changes.added_observations, record.version);
  record.observations_added = static_cast<int64_t>(changes.added_observations.size());
  record.observations_removed = static_cast<int64_t>(changes.removed_observations.size());

  std::optional<Extent> extent = tally.boundary_touched
                                     ? internal::ScanExtent(db, map.id)
                                     : internal::Union(map.info.extent, put.extent);
  if (map.info.tree_count == 0) extent.reset();
  internal::StampVersion(map.info, record, std::move(extent));
  internal::UpdateMapRow(db, map);
  internal::InsertVersion(db, map.id, record);
  return record;
}

}  // namespace

VersionRecord internal::RequireVersion(Database& db, const MapRow& map, int64_t version) {
  return RequireVersionImpl(db, map, version);
}

MapSnapshot SqliteMapStore::ReadMapVersion(const std::string& name, int64_t version) {
  internal::CheckName(name);
  internal::CheckVersionNumber(name, version);
  MapSnapshot snapshot;
  WithReader([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kRead);  // info and trees of one version
    const MapRow map = internal::RequireMap(db, name);
    snapshot.info = map.info;
    if (version == 0 || version == map.info.version) {
      snapshot.trees = TreesAtVersion(db, map, map.info.version);
      transaction.Commit();
      return;
    }
    const VersionRecord record = internal::RequireVersion(db, map, version);
    snapshot.trees = TreesAtVersion(db, map, version);
    transaction.Commit();
    snapshot.info = internal::InfoAtVersion(map.info, record, snapshot.trees);
  });
  return snapshot;
}

std::vector<VersionRecord> SqliteMapStore::ListVersions(const std::string& name, int64_t limit) {
  internal::CheckName(name);
  std::vector<VersionRecord> versions;
  WithReader([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kRead);
    const MapRow map = internal::RequireMap(db, name);
    Statement select(db,
                     "SELECT version FROM map_versions WHERE map_id = ?1 ORDER BY version DESC "
                     "LIMIT ?2");
    select.BindInt64(1, map.id);
    select.BindInt64(2, limit > 0 ? limit : -1);
    std::vector<int64_t> numbers;
    while (select.Step()) numbers.push_back(select.ColumnInt64(0));
    for (auto it = numbers.rbegin(); it != numbers.rend(); ++it) {
      versions.push_back(internal::RequireVersion(db, map, *it));
    }
    transaction.Commit();
  });
  return versions;
}

MapInfo SqliteMapStore::Merge(const std::string& name, const MergeNote& note,
                              const MergeFunction& merge) {
  internal::CheckName(name);
  MapInfo result;
  WithWriter([&](Database& db) {
    // IMMEDIATE: the write lock is taken before the first read, so what `merge` reads is the
    // version its changes apply to (no other writer, in this process or another, in between).
    Transaction transaction(db, Transaction::Kind::kWrite);
    MapRow map = internal::RequireMap(db, name);
    internal::CheckExpectedVersion(note, map.info);
    SqliteMergeReader reader(db, map);
    const MapChanges changes = merge(reader);
    if (changes.empty()) {
      result = map.info;  // nothing to write: no new version (the transaction rolls back)
      return;
    }
    ApplyChanges(db, map, note, changes);
    internal::CommitWrite(db, transaction, map.info);
    result = map.info;
  });
  return result;
}

}  // namespace forestmap::storage
