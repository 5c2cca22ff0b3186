// The SQLite session's observation rows: found by tree, by cell (storage::ObservationCell) or by
// source through partial indexes of current rows, closed by later versions.

#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "storage/sqlite/internal.h"

namespace forestmap::storage::sqlite {
namespace {

std::vector<ObservationRecord> ReadObservations(Statement& select) {
  return ReadAll(select, [](const Row& row) { return internal::ReadObservationRow(row); });
}

// Current rows of the trees `ids`, folded or not (`folded` 0 or 1).
std::vector<ObservationRecord> RowsOfTrees(Database& db, int64_t map_id,
                                           std::span<const int64_t> ids, int folded) {
  Statement select(db,
                   "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                   " FROM observations AS o INDEXED BY observations_of_tree WHERE "
                   "o.map_id = ?1 AND o.tree_id = ?2 AND o.folded = ?3 AND "
                   "o.valid_to = " FORESTMAP_CURRENT,
                   map_id);
  select.BindInt64(3, folded);
  std::vector<ObservationRecord> rows;
  for (const int64_t id : std::set<int64_t>(ids.begin(), ids.end())) {
    select.BindInt64(2, id);
    while (select.Step()) rows.push_back(internal::ReadObservationRow(Row(select)));
    select.Reset();
  }
  std::sort(rows.begin(), rows.end(),
            [](const ObservationRecord& a, const ObservationRecord& b) { return a.id < b.id; });
  return rows;
}

}  // namespace

std::vector<ObservationRecord> Session::ObservationsOfTrees(int64_t map_id,
                                                            std::span<const int64_t> ids) {
  return RowsOfTrees(db_, map_id, ids, 0);
}

std::vector<ObservationRecord> Session::FoldedObservationsOfTrees(int64_t map_id,
                                                                  std::span<const int64_t> ids) {
  return RowsOfTrees(db_, map_id, ids, 1);
}

std::vector<ObservationRecord> Session::ObservationsInCells(
    int64_t map_id, std::span<const ObservationCell> cells) {
  Statement select(db_,
                   "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                   " FROM observations AS o INDEXED BY observations_in_cell WHERE "
                   "o.map_id = ?1 AND o.cell_x = ?2 AND o.cell_y = ?3 AND "
                   "o.valid_to = " FORESTMAP_CURRENT " AND o.folded = 0",
                   map_id);
  std::vector<ObservationRecord> rows;
  for (const ObservationCell& cell : std::set<ObservationCell>(cells.begin(), cells.end())) {
    select.BindInt64(2, cell.x);
    select.BindInt64(3, cell.y);
    while (select.Step()) rows.push_back(internal::ReadObservationRow(Row(select)));
    select.Reset();
  }
  std::sort(rows.begin(), rows.end(),
            [](const ObservationRecord& a, const ObservationRecord& b) { return a.id < b.id; });
  return rows;
}

std::vector<ObservationRecord> Session::ObservationsOfSourceIn(int64_t map_id,
                                                               const std::string& source,
                                                               ObservationCell lo,
                                                               ObservationCell hi) {
  Statement select(db_,
                   "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                   " FROM observations AS o INDEXED BY observations_of_source WHERE "
                   "o.map_id = ?1 AND o.source = ?2 AND o.cell_x BETWEEN ?3 AND ?4 AND "
                   "o.cell_y BETWEEN ?5 AND ?6 AND o.valid_to = " FORESTMAP_CURRENT
                   " AND o.folded = 0 ORDER BY o.id",
                   map_id);
  select.BindText(2, source);
  select.BindInt64(3, lo.x);
  select.BindInt64(4, hi.x);
  select.BindInt64(5, lo.y);
  select.BindInt64(6, hi.y);
  return ReadAll(select, [](const Row& row) { return internal::ReadObservationRow(row); });
}

std::vector<ObservationRecord> Session::ObservationsOfSource(int64_t map_id,
                                                             const std::string& source) {
  Statement select(db_,
                   "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                   " FROM observations AS o WHERE "
                   "o.map_id = ?1 AND o.source = ?2 AND o.valid_to = " FORESTMAP_CURRENT
                   " ORDER BY o.id",
                   map_id, source);
  return ReadObservations(select);
}

void Session::InsertObservations(int64_t map_id, const std::vector<ObservationRecord>& rows,
                                 int64_t valid_from) {
  Statement insert(
      db_,
      "INSERT INTO observations (map_id, valid_from, valid_to, tree_id, source, "
      "frame_id, detection_index, x, y, z, dbh, weight_xy, weight_dbh, sensor_x, "
      "sensor_y, sensor_z, prior, cell_x, cell_y, folded, summary) VALUES (?1, ?2, "
      "" FORESTMAP_CURRENT
      ", ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, "
      "?20)");
  insert.Bind(1, map_id);
  insert.Bind(2, valid_from);
  for (const ObservationRecord& o : rows) {
    Binder values(insert, 3);
    internal::WriteObservationValues(values, o);
    insert.Run();
  }
}

std::vector<int64_t> Session::CloseObservations(int64_t map_id, std::span<const int64_t> ids,
                                                int64_t version) {
  Statement close(db_,
                  "UPDATE observations SET valid_to = ?2 WHERE id = ?3 AND map_id = ?1 AND "
                  "valid_to = " FORESTMAP_CURRENT,
                  map_id, version);
  std::vector<int64_t> closed;
  for (const int64_t id : ids) {
    close.BindInt64(3, id);
    close.Run();
    if (db_.Changes() == 1) closed.push_back(id);
  }
  return closed;
}

std::vector<ObservationRecord> Session::ClosedObservationsAt(int64_t map_id, int64_t version) {
  Statement select(db_,
                   "SELECT " FORESTMAP_OBSERVATION_COLUMNS
                   " FROM observations AS o INDEXED BY observations_history WHERE "
                   "o.map_id = ?1 AND o.valid_to != " FORESTMAP_CURRENT
                   " AND o.valid_from <= ?2 AND o.valid_to > ?2 ORDER BY o.id",
                   map_id, version);
  return ReadObservations(select);
}

int64_t Session::CloseObservationsAddedAfter(int64_t map_id, int64_t version, int64_t at) {
  Statement(db_,
            "UPDATE observations SET valid_to = ?3 WHERE map_id = ?1 AND valid_from > ?2 AND "
            "valid_to = " FORESTMAP_CURRENT,
            map_id, version, at)
      .Run();
  return db_.Changes();
}

}  // namespace forestmap::storage::sqlite
