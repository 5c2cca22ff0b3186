// PostgresMapStore: versions of shared maps (reading an old version, history, restore) and the
// merge transaction.

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <utility>

#include "storage/checks.h"
#include "storage/postgres/connection.h"
#include "storage/postgres/internal.h"
#include "storage/postgres/store.h"
#include "storage/store_steps.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;
using pg::Connection;
using pg::Params;
using pg::Transaction;
using pg_internal::Int64Array;
using pg_internal::MapRow;

std::vector<TreeRecord> TreesAtVersion(Connection& conn, const MapRow& map, int64_t version) {
  if (version == map.info.version) {
    return pg_internal::ReadTreeRows(
        conn.Exec("SELECT " FORESTMAP_PG_TREE_COLUMNS
                  " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_PG_CURRENT
                  " ORDER BY t.tree_id",
                  Params().Int64(map.id)),
        map.info.name);
  }
  return pg_internal::ReadTreeRows(
      conn.Exec("SELECT " FORESTMAP_PG_TREE_COLUMNS
                " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_PG_CURRENT
                " AND t.valid_from <= $2 UNION ALL SELECT " FORESTMAP_PG_TREE_COLUMNS
                " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to <> " FORESTMAP_PG_CURRENT
                " AND t.valid_from <= $2 AND t.valid_to > $2 ORDER BY 1",
                Params().Int64(map.id).Int64(version)),
      map.info.name);
}

// Read access of a merge: the connection inside its write transaction, holding the map's lock.
class PostgresMergeReader final : public MergeReader {
 public:
  PostgresMergeReader(Connection& conn, const MapRow& map) : conn_(conn), map_(map) {}

  const MapInfo& map() const override { return map_.info; }

  std::vector<TreeRecord> TreesInBox(const Extent& box) override {
    internal::CheckBox(map_.info.name, box);
    return pg_internal::CurrentTreesInBox(conn_, map_, box);
  }

  std::vector<TreeRecord> TreesById(std::span<const int64_t> ids) override {
    return pg_internal::ReadTreeRows(
        conn_.Exec("SELECT " FORESTMAP_PG_TREE_COLUMNS
                   " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_PG_CURRENT
                   " AND t.tree_id = ANY($2::bigint[]) ORDER BY t.tree_id",
                   Params().Int64(map_.id).Text(Int64Array({ids.begin(), ids.end()}))),
        map_.info.name);
  }

  std::vector<ObservationRecord> ObservationsOfTrees(std::span<const int64_t> ids) override {
    return pg_internal::ReadObservationRows(conn_.Exec(
        "SELECT " FORESTMAP_PG_OBSERVATION_COLUMNS
        " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to = " FORESTMAP_PG_CURRENT
        " AND o.tree_id = ANY($2::bigint[]) ORDER BY o.id",
        Params().Int64(map_.id).Text(Int64Array({ids.begin(), ids.end()}))));
  }

  std::vector<ObservationRecord> ObservationsInCells(
      std::span<const ObservationCell> cells) override {
    std::vector<int64_t> xs, ys;
    for (const ObservationCell& cell : cells) {
      xs.push_back(cell.x);
      ys.push_back(cell.y);
    }
    return pg_internal::ReadObservationRows(conn_.Exec(
        "SELECT " FORESTMAP_PG_OBSERVATION_COLUMNS
        " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to = " FORESTMAP_PG_CURRENT
        " AND (o.cell_x, o.cell_y) IN (SELECT * FROM unnest($2::bigint[], "
        "$3::bigint[])) ORDER BY o.id",
        Params().Int64(map_.id).Text(Int64Array(xs)).Text(Int64Array(ys))));
  }

  std::vector<ObservationRecord> ObservationsOfSource(const std::string& source) override {
    return pg_internal::ReadObservationRows(conn_.Exec(
        "SELECT " FORESTMAP_PG_OBSERVATION_COLUMNS
        " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to = " FORESTMAP_PG_CURRENT
        " AND o.source = $2 ORDER BY o.id",
        Params().Int64(map_.id).Text(source)));
  }

  int64_t NextFreeTreeId() override {
    const pg::Result result =
        conn_.Exec("SELECT MAX(tree_id) FROM trees WHERE map_id = $1", Params().Int64(map_.id));
    if (result.IsNull(0, 0)) return 1;
    const int64_t max_id = result.Int64(0, 0);
    if (max_id == std::numeric_limits<int64_t>::max()) {
      throw StorageError(Code::kInvalidArgument,
                         "map '" + map_.info.name + "': no free tree ids left for new trees");
    }
    return std::max<int64_t>(max_id + 1, 1);
  }

 private:
  Connection& conn_;
  const MapRow& map_;
};

// Closes the current rows of trees `ids` at `version`, adjusting the map's counts for the rows
// that left; returns the ids that had a current row. Sets `boundary` when a closed tree lay on
// the extent's border (the extent must then be rescanned).
std::set<int64_t> CloseTrees(Connection& conn, MapRow& map, const std::vector<int64_t>& ids,
                             int64_t version, bool& boundary) {
  const pg::Result closed = conn.Exec(
      "UPDATE trees SET valid_to = $2 WHERE map_id = $1 AND valid_to = " FORESTMAP_PG_CURRENT
      " AND tree_id = ANY($3::bigint[]) RETURNING tree_id, status, x, y",
      Params().Int64(map.id).Int64(version).Text(Int64Array(ids)));
  std::set<int64_t> found;
  MapInfo& info = map.info;
  for (int r = 0; r < closed.rows(); ++r) {
    found.insert(closed.Int64(r, 0));
    info.tree_count -= 1;
    info.confirmed_count -= closed.Int64(r, 1) != 0 ? 1 : 0;
    if (internal::OnBorder(info.extent, closed.Double(r, 2), closed.Double(r, 3))) boundary = true;
  }
  return found;
}

// Writes `changes` as version map.version + 1 and updates `map` (row and info).
void ApplyChanges(Connection& conn, MapRow& map, const MergeNote& note, const MapChanges& changes) {
  internal::CheckPutTrees(map.info.name, changes);
  VersionRecord record = internal::NextVersion(map.info, note.kind, note.source);
  bool boundary = false;
  const std::set<int64_t> removed =
      CloseTrees(conn, map, changes.removed_trees, record.version, boundary);
  for (const int64_t id : changes.removed_trees) {
    if (removed.count(id) == 0) throw internal::TreeToRemoveMissing(map.info.name, id);
  }
  record.trees_removed = static_cast<int64_t>(removed.size());
  const internal::PutTrees put = internal::CountPutTrees(map.info, changes.put_trees);
  record.trees_updated =
      static_cast<int64_t>(CloseTrees(conn, map, put.ids, record.version, boundary).size());
  record.trees_added = static_cast<int64_t>(put.ids.size()) - record.trees_updated;
  pg_internal::InsertTrees(conn, map, changes.put_trees, put.ids, record.version);

  const pg::Result closed = conn.Exec(
      "UPDATE observations SET valid_to = $2 WHERE map_id = $1 AND valid_to = " FORESTMAP_PG_CURRENT
      " AND id = ANY($3::bigint[]) RETURNING id",
      Params().Int64(map.id).Int64(record.version).Text(Int64Array(changes.removed_observations)));
  std::set<int64_t> closed_ids;
  for (int r = 0; r < closed.rows(); ++r) closed_ids.insert(closed.Int64(r, 0));
  for (const int64_t id : changes.removed_observations) {
    if (closed_ids.count(id) == 0) throw internal::ObservationToRemoveMissing(map.info.name, id);
  }
  pg_internal::InsertObservations(conn, map.id, changes.added_observations, record.version);
  record.observations_added = static_cast<int64_t>(changes.added_observations.size());
  record.observations_removed = static_cast<int64_t>(closed_ids.size());

  std::optional<Extent> extent = boundary ? pg_internal::ScanExtent(conn, map.id)
                                          : internal::Union(map.info.extent, put.extent);
  if (map.info.tree_count == 0) extent.reset();
  internal::StampVersion(map.info, record, std::move(extent));
  pg_internal::UpdateMapRow(conn, map);
  pg_internal::InsertVersion(conn, map.id, record);
}

// Restore's observation rows: rows valid at `version` but closed since come back as copies
// valid from `next`; current rows added after `version` are closed. Counts go into `record`.
void RestoreObservations(Connection& conn, const MapRow& map, int64_t version, int64_t next,
                         VersionRecord& record) {
  const Params at = Params().Int64(map.id).Int64(version);
  const std::vector<ObservationRecord> observation_copies =
      pg_internal::ReadObservationRows(conn.Exec(
          "SELECT " FORESTMAP_PG_OBSERVATION_COLUMNS
          " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to <> " FORESTMAP_PG_CURRENT
          " AND o.valid_from <= $2 AND o.valid_to > $2 ORDER BY o.id",
          at));
  record.observations_removed =
      conn.Exec(
              "UPDATE observations SET valid_to = $3 WHERE map_id = $1 AND valid_from > $2 "
              "AND valid_to = " FORESTMAP_PG_CURRENT,
              Params().Int64(map.id).Int64(version).Int64(next))
          .affected();
  pg_internal::InsertObservations(conn, map.id, observation_copies, next);
  record.observations_added = static_cast<int64_t>(observation_copies.size());
}

}  // namespace

MapSnapshot PostgresMapStore::ReadMapVersion(const std::string& name, int64_t version) {
  internal::CheckName(name);
  internal::CheckVersionNumber(name, version);
  MapSnapshot snapshot;
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kRead);  // info and trees of one version
    const MapRow map = pg_internal::RequireMap(conn, name);
    snapshot.info = map.info;
    if (version == 0 || version == map.info.version) {
      snapshot.trees = TreesAtVersion(conn, map, map.info.version);
      transaction.Commit();
      return;
    }
    const VersionRecord record = pg_internal::RequireVersion(conn, map, version);
    snapshot.trees = TreesAtVersion(conn, map, version);
    transaction.Commit();
    snapshot.info = internal::InfoAtVersion(map.info, record, snapshot.trees);
  });
  return snapshot;
}

std::vector<VersionRecord> PostgresMapStore::ListVersions(const std::string& name, int64_t limit) {
  internal::CheckName(name);
  std::vector<VersionRecord> versions;
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kRead);
    const MapRow map = pg_internal::RequireMap(conn, name);
    const pg::Result numbers = conn.Exec(
        "SELECT version FROM map_versions WHERE map_id = $1 ORDER BY version DESC LIMIT $2",
        Params().Int64(map.id).Int64(limit > 0 ? limit : std::numeric_limits<int64_t>::max()));
    for (int r = numbers.rows() - 1; r >= 0; --r) {
      versions.push_back(pg_internal::RequireVersion(conn, map, numbers.Int64(r, 0)));
    }
    transaction.Commit();
  });
  return versions;
}

MapInfo PostgresMapStore::RestoreVersion(const std::string& name, int64_t version) {
  internal::CheckName(name);
  MapInfo result;
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kWrite);
    MapRow map = pg_internal::LockMap(conn, name);
    const VersionRecord old = pg_internal::RequireVersion(conn, map, version);
    const int64_t next = map.info.version + 1;
    // Rows valid at `version` but no longer current come back as copies; current rows that
    // `version` did not have are closed. Rows valid at both simply stay.
    const Params at = Params().Int64(map.id).Int64(version);
    const std::vector<TreeRecord> copies = pg_internal::ReadTreeRows(
        conn.Exec("SELECT " FORESTMAP_PG_TREE_COLUMNS
                  " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to <> " FORESTMAP_PG_CURRENT
                  " AND t.valid_from <= $2 AND t.valid_to > $2",
                  at),
        name);
    const pg::Result closed_rows = conn.Exec(
        "UPDATE trees SET valid_to = $3 WHERE map_id = $1 AND valid_from > $2 AND "
        "valid_to = " FORESTMAP_PG_CURRENT " RETURNING tree_id",
        Params().Int64(map.id).Int64(version).Int64(next));
    std::set<int64_t> closed;
    for (int r = 0; r < closed_rows.rows(); ++r) closed.insert(closed_rows.Int64(r, 0));
    std::vector<int64_t> ids;
    VersionRecord record;
    for (const TreeRecord& tree : copies) {
      ids.push_back(*tree.id);
      ++(closed.count(*tree.id) ? record.trees_updated : record.trees_added);
    }
    record.trees_removed = static_cast<int64_t>(closed.size()) - record.trees_updated;
    pg_internal::InsertTrees(conn, map, copies, ids, next);

    RestoreObservations(conn, map, version, next, record);

    internal::StampRestore(map.info, record, old, pg_internal::ScanExtent(conn, map.id));
    pg_internal::UpdateMapRow(conn, map);
    pg_internal::InsertVersion(conn, map.id, record);
    pg_internal::CommitWrite(conn, transaction, map.info);
    result = map.info;
  });
  return result;
}

MapInfo PostgresMapStore::Merge(const std::string& name, const MergeNote& note,
                                const MergeFunction& merge) {
  internal::CheckName(name);
  MapInfo result;
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kWrite);
    // The map's lock is held to the commit: what `merge` reads is the version its changes apply
    // to, whichever replica the other writers of this map go through.
    MapRow map = pg_internal::LockMap(conn, name);
    internal::CheckExpectedVersion(note, map.info);
    PostgresMergeReader reader(conn, map);
    const MapChanges changes = merge(reader);
    if (changes.empty()) {
      result = map.info;  // nothing to write: no new version (the transaction rolls back)
      return;
    }
    ApplyChanges(conn, map, note, changes);
    pg_internal::CommitWrite(conn, transaction, map.info);
    result = map.info;
  });
  return result;
}

}  // namespace forestmap::storage
