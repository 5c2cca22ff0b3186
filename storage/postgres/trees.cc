// The PostgreSQL session's tree and observation rows: inserted by INSERT ... SELECT FROM
// unnest(...) of up to kRowsPerInsert rows, found through the partial indexes of current rows
// (the spatial index is a B-tree on (map_id, x, y) of current rows: a box query is a range on x
// filtered by y), closed by later versions.

#include <algorithm>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "storage/postgres/internal.h"

namespace forestmap::storage::pg {
namespace {

using Code = StorageError::Code;
constexpr size_t kRowsPerInsert = PostgresMapStore::kRowsPerInsert;

std::vector<TreeRecord> ReadTrees(const Result& result, const MapRow& map) {
  return ReadAll(result, [&](const Row& row) { return internal::ReadTreeRow(row, map.info.name); });
}

std::vector<ObservationRecord> ReadObservations(const Result& result) {
  return ReadAll(result, [](const Row& row) { return internal::ReadObservationRow(row); });
}

// The first tree of `trees` whose id is already current in the map, if any.
std::optional<size_t> FirstTakenId(Connection& conn, int64_t map_id,
                                   const std::vector<int64_t>& ids) {
  const Result taken =
      conn.Exec("SELECT tree_id FROM trees WHERE map_id = $1 AND valid_to = " FORESTMAP_CURRENT
                " AND tree_id = ANY($2::bigint[])",
                Params().Int64(map_id).Text(Int64Array(ids)));
  if (taken.rows() == 0) return std::nullopt;
  std::set<int64_t> taken_ids;
  for (int r = 0; r < taken.rows(); ++r) taken_ids.insert(taken.Int64(r, 0));
  for (size_t i = 0; i < ids.size(); ++i) {
    if (taken_ids.count(ids[i]) != 0) return i;
  }
  return std::nullopt;
}

// Runs the INSERT ... SELECT FROM unnest(...) `sql` ($1 map id, $2 valid_from, then one array
// per column) over rows 0 .. count - 1, kRowsPerInsert at a time; `add(columns, i)` writes row i.
template <typename AddRow>
void InsertRows(Connection& conn, const char* sql, int64_t map_id, int64_t valid_from, size_t count,
                size_t column_count, const AddRow& add) {
  for (size_t begin = 0; begin < count; begin += kRowsPerInsert) {
    ColumnArrays columns(column_count);
    for (size_t i = begin; i < std::min(count, begin + kRowsPerInsert); ++i) {
      add(columns, i);
      columns.EndRow();
    }
    Params params;
    params.Int64(map_id).Int64(valid_from);
    columns.AppendTo(params);
    conn.Exec(sql, params);
  }
}

// $1 map id, $2 version, $3 after id, $4 limit, $5..$8 the box (infinite without one).
Params PageParams(int64_t map_id, const TreePageQuery& query) {
  const Extent box = internal::PageBox(query);
  Params params;
  params.Int64(map_id).Int64(query.version);
  params.Int64(internal::PageAfterId(query)).Int64(query.limit);
  params.Double(box.min_x).Double(box.max_x).Double(box.min_y).Double(box.max_y);
  return params;
}

}  // namespace

std::optional<int64_t> MaxCurrentTreeId(Connection& conn, int64_t map_id) {
  const Result max = conn.Exec(
      "SELECT MAX(tree_id) FROM trees WHERE map_id = $1 AND valid_to = " FORESTMAP_CURRENT,
      Params().Int64(map_id));
  if (max.IsNull(0, 0)) return std::nullopt;
  return max.Int64(0, 0);
}

// ---- Trees ----

std::vector<TreeRecord> Session::CurrentTrees(const MapRow& map) {
  return ReadTrees(conn_.Exec("SELECT " FORESTMAP_TREE_COLUMNS
                              " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = "
                              "" FORESTMAP_CURRENT " ORDER BY t.tree_id",
                              Params().Int64(map.id)),
                   map);
}

std::vector<TreeRecord> Session::TreesAtVersion(const MapRow& map, int64_t version) {
  return ReadTrees(
      conn_.Exec("SELECT " FORESTMAP_TREE_COLUMNS
                 " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_CURRENT
                 " AND t.valid_from <= $2 UNION ALL SELECT " FORESTMAP_TREE_COLUMNS
                 " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to <> " FORESTMAP_CURRENT
                 " AND t.valid_from <= $2 AND t.valid_to > $2 ORDER BY 1",
                 Params().Int64(map.id).Int64(version)),
      map);
}

std::vector<TreeRecord> Session::TreesInBox(const MapRow& map, const Extent& box) {
  return ReadTrees(
      conn_.Exec(
          "SELECT " FORESTMAP_TREE_COLUMNS
          " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_CURRENT
          " AND t.x >= $2 AND t.x <= $3 AND t.y >= $4 AND t.y <= $5 ORDER BY t.tree_id",
          Params().Int64(map.id).Double(box.min_x).Double(box.max_x).Double(box.min_y).Double(
              box.max_y)),
      map);
}

std::vector<TreeRecord> Session::TreesById(const MapRow& map, std::span<const int64_t> ids) {
  return ReadTrees(
      conn_.Exec("SELECT " FORESTMAP_TREE_COLUMNS
                 " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_CURRENT
                 " AND t.tree_id = ANY($2::bigint[]) ORDER BY t.tree_id",
                 Params().Int64(map.id).Text(Int64Array(ids))),
      map);
}

std::vector<TreeRecord> Session::CurrentPage(const MapRow& map, const TreePageQuery& query) {
  return ReadTrees(
      conn_.Exec("SELECT " FORESTMAP_TREE_COLUMNS
                 " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_CURRENT
                 " AND t.valid_from <= $2 AND t.tree_id > $3 AND t.x >= $5 AND t.x <= $6 AND "
                 "t.y >= $7 AND t.y <= $8 ORDER BY t.tree_id LIMIT $4",
                 PageParams(map.id, query)),
      map);
}

std::vector<TreeRecord> Session::ClosedPage(const MapRow& map, const TreePageQuery& query) {
  return ReadTrees(
      conn_.Exec("SELECT " FORESTMAP_TREE_COLUMNS
                 " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to <> " FORESTMAP_CURRENT
                 " AND t.valid_from <= $2 AND t.valid_to > $2 AND t.tree_id > $3 AND "
                 "t.x >= $5 AND t.x <= $6 AND t.y >= $7 AND t.y <= $8 ORDER BY t.tree_id "
                 "LIMIT $4",
                 PageParams(map.id, query)),
      map);
}

std::optional<int64_t> Session::MaxCurrentTreeId(int64_t map_id) {
  return pg::MaxCurrentTreeId(conn_, map_id);
}

std::optional<int64_t> Session::MaxTreeIdEver(int64_t map_id) {
  const Result result =
      conn_.Exec("SELECT MAX(tree_id) FROM trees WHERE map_id = $1", Params().Int64(map_id));
  if (result.IsNull(0, 0)) return std::nullopt;
  return result.Int64(0, 0);
}

void Session::InsertTrees(const MapRow& map, const std::vector<TreeRecord>& trees,
                          const std::vector<int64_t>& ids, int64_t valid_from) {
  if (const std::optional<size_t> taken = FirstTakenId(conn_, map.id, ids)) {
    throw StorageError(Code::kInvalidArgument, "map '" + map.info.name +
                                                   "': " + internal::TreeLabel(trees, *taken) +
                                                   ": tree id already exists in the map");
  }
  InsertRows(
      conn_,
      "INSERT INTO trees (map_id, valid_from, valid_to, tree_id, x, y, z, dbh, attributes, status, "
      "observations, position_sigma, dbh_sigma, last_seen_unix_ms, evidence) SELECT $1, "
      "$2, " FORESTMAP_CURRENT
      ", u.* FROM unnest($3::bigint[], $4::float8[], $5::float8[], $6::float8[], $7::float8[], "
      "$8::text[], $9::smallint[], $10::bigint[], $11::float8[], $12::float8[], $13::bigint[], "
      "$14::text[]) AS u",
      map.id, valid_from, trees.size(), 12, [&](ColumnArrays& columns, size_t i) {
        internal::WriteTreeValues(columns, ids[i], trees[i],
                                  internal::StoredAttributes(map.info.name, trees, i));
      });
}

std::vector<ClosedTree> Session::CloseTrees(int64_t map_id, std::span<const int64_t> ids,
                                            int64_t version) {
  return ReadAll(
      conn_.Exec(
          "UPDATE trees SET valid_to = $2 WHERE map_id = $1 AND valid_to = " FORESTMAP_CURRENT
          " AND tree_id = ANY($3::bigint[]) RETURNING tree_id, status, x, y",
          Params().Int64(map_id).Int64(version).Text(Int64Array(ids))),
      [](const Row& row) {
        return ClosedTree{row.Int64(0), row.Int64(1) != 0, row.Double(2), row.Double(3)};
      });
}

int64_t Session::CloseAllRows(int64_t map_id, int64_t version) {
  const Params close = Params().Int64(map_id).Int64(version);
  conn_.Exec("UPDATE trees SET valid_to = $2 WHERE map_id = $1 AND valid_to = " FORESTMAP_CURRENT,
             close);
  return conn_
      .Exec(
          "UPDATE observations SET valid_to = $2 WHERE map_id = $1 AND "
          "valid_to = " FORESTMAP_CURRENT,
          close)
      .affected();
}

std::vector<TreeRecord> Session::ClosedTreesAt(const MapRow& map, int64_t version) {
  return ReadTrees(
      conn_.Exec("SELECT " FORESTMAP_TREE_COLUMNS
                 " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to <> " FORESTMAP_CURRENT
                 " AND t.valid_from <= $2 AND t.valid_to > $2",
                 Params().Int64(map.id).Int64(version)),
      map);
}

std::vector<int64_t> Session::CloseTreesAddedAfter(int64_t map_id, int64_t version, int64_t at) {
  return ReadAll(conn_.Exec("UPDATE trees SET valid_to = $3 WHERE map_id = $1 AND valid_from > $2 "
                            "AND valid_to = " FORESTMAP_CURRENT " RETURNING tree_id",
                            Params().Int64(map_id).Int64(version).Int64(at)),
                 [](const Row& row) { return row.Int64(0); });
}

// ---- Observations ----

std::vector<ObservationRecord> Session::ObservationsOfTrees(int64_t map_id,
                                                            std::span<const int64_t> ids) {
  return ReadObservations(
      conn_.Exec("SELECT " FORESTMAP_OBSERVATION_COLUMNS
                 " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to = " FORESTMAP_CURRENT
                 " AND o.tree_id = ANY($2::bigint[]) AND NOT o.folded ORDER BY o.id",
                 Params().Int64(map_id).Text(Int64Array(ids))));
}

std::vector<ObservationRecord> Session::FoldedObservationsOfTrees(int64_t map_id,
                                                                  std::span<const int64_t> ids) {
  return ReadObservations(
      conn_.Exec("SELECT " FORESTMAP_OBSERVATION_COLUMNS
                 " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to = " FORESTMAP_CURRENT
                 " AND o.tree_id = ANY($2::bigint[]) AND o.folded ORDER BY o.id",
                 Params().Int64(map_id).Text(Int64Array(ids))));
}

std::vector<ObservationRecord> Session::ObservationsInCells(
    int64_t map_id, std::span<const ObservationCell> cells) {
  std::vector<int64_t> xs, ys;
  for (const ObservationCell& cell : cells) {
    xs.push_back(cell.x);
    ys.push_back(cell.y);
  }
  return ReadObservations(conn_.Exec(
      "SELECT " FORESTMAP_OBSERVATION_COLUMNS
      " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to = " FORESTMAP_CURRENT
      " AND NOT o.folded AND (o.cell_x, o.cell_y) IN (SELECT * FROM unnest($2::bigint[], "
      "$3::bigint[])) ORDER BY o.id",
      Params().Int64(map_id).Text(Int64Array(xs)).Text(Int64Array(ys))));
}

std::vector<ObservationRecord> Session::ObservationsOfSourceIn(int64_t map_id,
                                                               const std::string& source,
                                                               ObservationCell lo,
                                                               ObservationCell hi) {
  return ReadObservations(conn_.Exec(
      "SELECT " FORESTMAP_OBSERVATION_COLUMNS
      " FROM observations AS o WHERE o.map_id = $1 AND o.source = $2 AND o.cell_x BETWEEN $3 "
      "AND $4 AND o.cell_y BETWEEN $5 AND $6 AND o.valid_to = " FORESTMAP_CURRENT
      " AND NOT o.folded ORDER BY o.id",
      Params().Int64(map_id).Text(source).Int64(lo.x).Int64(hi.x).Int64(lo.y).Int64(hi.y)));
}

std::vector<ObservationRecord> Session::ObservationsOfSource(int64_t map_id,
                                                             const std::string& source) {
  return ReadObservations(
      conn_.Exec("SELECT " FORESTMAP_OBSERVATION_COLUMNS
                 " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to = " FORESTMAP_CURRENT
                 " AND o.source = $2 ORDER BY o.id",
                 Params().Int64(map_id).Text(source)));
}

void Session::InsertObservations(int64_t map_id, const std::vector<ObservationRecord>& rows,
                                 int64_t valid_from) {
  InsertRows(
      conn_,
      "INSERT INTO observations (map_id, valid_from, valid_to, tree_id, source, frame_id, "
      "detection_index, x, y, z, dbh, weight_xy, weight_dbh, sensor_x, sensor_y, sensor_z, "
      "prior, cell_x, cell_y, folded, summary) SELECT $1, $2, " FORESTMAP_CURRENT
      ", u.tree_id, u.source, u.frame_id, u.detection_index, u.x, u.y, u.z, u.dbh, "
      "u.weight_xy, u.weight_dbh, u.sensor_x, u.sensor_y, u.sensor_z, u.prior, u.cell_x, "
      "u.cell_y, u.folded, u.summary FROM unnest($3::bigint[], $4::text[], $5::bigint[], "
      "$6::integer[], $7::float8[], $8::float8[], $9::float8[], $10::float8[], $11::float8[], "
      "$12::float8[], $13::float8[], $14::float8[], $15::float8[], $16::boolean[], "
      "$17::bigint[], $18::bigint[], $19::boolean[], $20::text[], $21::bigint[]) AS "
      "u(tree_id, source, frame_id, detection_index, x, y, z, dbh, weight_xy, weight_dbh, "
      "sensor_x, sensor_y, sensor_z, prior, cell_x, cell_y, folded, summary, ord) "
      "ORDER BY u.ord",
      map_id, valid_from, rows.size(), 19, [&](ColumnArrays& columns, size_t i) {
        internal::WriteObservationValues(columns, rows[i]);
        columns.Int64(static_cast<int64_t>(i));  // keeps the ids in the order of the rows
      });
}

std::vector<int64_t> Session::CloseObservations(int64_t map_id, std::span<const int64_t> ids,
                                                int64_t version) {
  return ReadAll(
      conn_.Exec("UPDATE observations SET valid_to = $2 WHERE map_id = $1 AND valid_to = "
                 "" FORESTMAP_CURRENT " AND id = ANY($3::bigint[]) RETURNING id",
                 Params().Int64(map_id).Int64(version).Text(Int64Array(ids))),
      [](const Row& row) { return row.Int64(0); });
}

std::vector<ObservationRecord> Session::ClosedObservationsAt(int64_t map_id, int64_t version) {
  return ReadObservations(
      conn_.Exec("SELECT " FORESTMAP_OBSERVATION_COLUMNS
                 " FROM observations AS o WHERE o.map_id = $1 AND o.valid_to <> " FORESTMAP_CURRENT
                 " AND o.valid_from <= $2 AND o.valid_to > $2 ORDER BY o.id",
                 Params().Int64(map_id).Int64(version)));
}

int64_t Session::CloseObservationsAddedAfter(int64_t map_id, int64_t version, int64_t at) {
  return conn_
      .Exec(
          "UPDATE observations SET valid_to = $3 WHERE map_id = $1 AND valid_from > $2 "
          "AND valid_to = " FORESTMAP_CURRENT,
          Params().Int64(map_id).Int64(version).Int64(at))
      .affected();
}

}  // namespace forestmap::storage::pg
