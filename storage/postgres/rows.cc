// PostgresMapStore: the schema and row-level helpers (maps, trees, observations, history).

#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>

#include "storage/attribute_json.h"
#include "storage/checks.h"
#include "storage/postgres/internal.h"
#include "storage/store_steps.h"

namespace forestmap::storage::pg_internal {
namespace {

using Code = StorageError::Code;
using internal::EncodeAttributes;
using pg::Params;

// Step i takes the schema from version i to i + 1 (pg::MigrateSchema). Never edit a shipped
// step: append one and bump PostgresMapStore::kSchemaVersion. The tables mirror the SQLite
// store's schema version 3 (storage/sqlite_schema.cc): rows carry [valid_from, valid_to), with
// partial indexes on current rows. The spatial index is a B-tree on (map_id, x, y) of current
// rows: a box query is a range on x filtered by y. Names sort bytewise (COLLATE "C").
constexpr const char* kStep1 = R"sql(
CREATE TABLE maps (
  id BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  name TEXT COLLATE "C" NOT NULL UNIQUE,
  description TEXT NOT NULL,
  crs TEXT NOT NULL,
  version BIGINT NOT NULL,
  tree_count BIGINT NOT NULL,
  confirmed_count BIGINT NOT NULL DEFAULT 0,
  min_x DOUBLE PRECISION, min_y DOUBLE PRECISION,  -- NULL for an empty map
  max_x DOUBLE PRECISION, max_y DOUBLE PRECISION,
  created_unix_ms BIGINT NOT NULL,
  updated_unix_ms BIGINT NOT NULL
);
CREATE TABLE trees (
  map_id BIGINT NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  tree_id BIGINT NOT NULL,
  valid_from BIGINT NOT NULL,  -- first map version holding this row
  valid_to BIGINT NOT NULL,    -- first map version no longer holding it; 2^63-1 while current
  x DOUBLE PRECISION NOT NULL,
  y DOUBLE PRECISION NOT NULL,
  z DOUBLE PRECISION,
  dbh DOUBLE PRECISION,
  attributes TEXT,  -- JSON object of strings, NULL when there are none
  status SMALLINT NOT NULL,  -- 0 candidate, 1 confirmed
  observations BIGINT NOT NULL,
  position_sigma DOUBLE PRECISION,  -- m
  dbh_sigma DOUBLE PRECISION        -- m
);
CREATE UNIQUE INDEX trees_current ON trees (map_id, tree_id)
  WHERE valid_to = 9223372036854775807;
CREATE INDEX trees_history ON trees (map_id, tree_id, valid_from)
  WHERE valid_to <> 9223372036854775807;
CREATE INDEX trees_current_xy ON trees (map_id, x, y) WHERE valid_to = 9223372036854775807;
CREATE TABLE observations (
  id BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
  map_id BIGINT NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  tree_id BIGINT NOT NULL,
  valid_from BIGINT NOT NULL,
  valid_to BIGINT NOT NULL,
  source TEXT NOT NULL,
  frame_id BIGINT NOT NULL,
  detection_index INTEGER NOT NULL,
  x DOUBLE PRECISION NOT NULL,
  y DOUBLE PRECISION NOT NULL,
  z DOUBLE PRECISION,
  dbh DOUBLE PRECISION,
  weight_xy DOUBLE PRECISION NOT NULL,   -- 1/m^2
  weight_dbh DOUBLE PRECISION NOT NULL,  -- 1/m^2
  sensor_x DOUBLE PRECISION NOT NULL,
  sensor_y DOUBLE PRECISION NOT NULL,
  sensor_z DOUBLE PRECISION NOT NULL,
  prior BOOLEAN NOT NULL,
  cell_x BIGINT NOT NULL,  -- storage::ObservationCell of (x, y)
  cell_y BIGINT NOT NULL
);
CREATE INDEX observations_of_tree ON observations (map_id, tree_id)
  WHERE valid_to = 9223372036854775807;
CREATE INDEX observations_of_source ON observations (map_id, source)
  WHERE valid_to = 9223372036854775807;
CREATE INDEX observations_in_cell ON observations (map_id, cell_x, cell_y)
  WHERE valid_to = 9223372036854775807;
CREATE INDEX observations_history ON observations (map_id, valid_from)
  WHERE valid_to <> 9223372036854775807;
CREATE TABLE map_versions (
  map_id BIGINT NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version BIGINT NOT NULL,
  created_unix_ms BIGINT NOT NULL,
  kind INTEGER NOT NULL,  -- storage::VersionKind
  source TEXT NOT NULL,
  tree_count BIGINT NOT NULL,
  confirmed_count BIGINT NOT NULL,
  trees_added BIGINT NOT NULL,
  trees_updated BIGINT NOT NULL,
  trees_removed BIGINT NOT NULL,
  observations_added BIGINT NOT NULL,
  observations_removed BIGINT NOT NULL,
  restored_from BIGINT NOT NULL,
  PRIMARY KEY (map_id, version)
);
)sql";

// The first tree of `trees` whose id is already current in the map, if any.
std::optional<size_t> FirstTakenId(pg::Connection& conn, int64_t map_id,
                                   const std::vector<int64_t>& ids) {
  const pg::Result taken =
      conn.Exec("SELECT tree_id FROM trees WHERE map_id = $1 AND valid_to = " FORESTMAP_PG_CURRENT
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

}  // namespace

// Step 2 (issue 15): answers of writes made with a client request id (exactly-once writes),
// the answer bytes as hex text.
constexpr const char* kStep2 = R"sql(
CREATE TABLE request_log (
  request_id TEXT COLLATE "C" PRIMARY KEY,
  rpc TEXT NOT NULL,
  response_hex TEXT NOT NULL,
  created_unix_ms BIGINT NOT NULL
);
CREATE INDEX request_log_by_time ON request_log (created_unix_ms);
)sql";

const std::vector<const char*>& SchemaSteps() {
  static const std::vector<const char*> steps = {kStep1, kStep2};
  return steps;
}

std::string Int64Array(const std::vector<int64_t>& values) {
  pg::ArrayLiteral array;
  for (const int64_t value : values) array.Int64(value);
  return array.Finish();
}

MapRow ReadMapRow(const pg::Result& result, int row) {
  MapRow map;
  map.id = result.Int64(row, 0);
  map.info.name = result.Text(row, 1);
  map.info.description = result.Text(row, 2);
  map.info.crs = result.Text(row, 3);
  map.info.version = result.Int64(row, 4);
  map.info.tree_count = result.Int64(row, 5);
  if (!result.IsNull(row, 6)) {
    map.info.extent = Extent{result.Double(row, 6), result.Double(row, 7), result.Double(row, 8),
                             result.Double(row, 9)};
  }
  map.info.created_unix_ms = result.Int64(row, 10);
  map.info.updated_unix_ms = result.Int64(row, 11);
  map.info.confirmed_count = result.Int64(row, 12);
  return map;
}

MapRow RequireMap(pg::Connection& conn, const std::string& name) {
  const pg::Result result = conn.Exec(
      "SELECT " FORESTMAP_PG_MAP_COLUMNS " FROM maps WHERE name = $1", Params().Text(name));
  if (result.rows() == 0) throw StorageError(Code::kNotFound, "map '" + name + "' does not exist");
  return ReadMapRow(result, 0);
}

MapRow LockMap(pg::Connection& conn, const std::string& name) {
  const int64_t id = RequireMap(conn, name).id;
  conn.Exec("SELECT pg_advisory_xact_lock($1)", Params().Int64(id));
  // READ COMMITTED: this statement sees every write committed before the lock was granted.
  // The map may have been deleted (or deleted and re-created) meanwhile.
  const MapRow map = RequireMap(conn, name);
  if (map.id != id) return LockMap(conn, name);
  return map;
}

void UpdateMapRow(pg::Connection& conn, const MapRow& map) {
  const MapInfo& info = map.info;
  Params params;
  params.Int64(map.id).Int64(info.version).Int64(info.tree_count);
  params.OptionalDouble(info.extent ? std::optional(info.extent->min_x) : std::nullopt);
  params.OptionalDouble(info.extent ? std::optional(info.extent->min_y) : std::nullopt);
  params.OptionalDouble(info.extent ? std::optional(info.extent->max_x) : std::nullopt);
  params.OptionalDouble(info.extent ? std::optional(info.extent->max_y) : std::nullopt);
  params.Int64(info.updated_unix_ms).Int64(info.confirmed_count);
  conn.Exec(
      "UPDATE maps SET version = $2, tree_count = $3, min_x = $4, min_y = $5, max_x = $6, "
      "max_y = $7, updated_unix_ms = $8, confirmed_count = $9 WHERE id = $1",
      params);
}

std::optional<Extent> ScanExtent(pg::Connection& conn, int64_t map_id) {
  const pg::Result scan = conn.Exec(
      "SELECT MIN(x), MIN(y), MAX(x), MAX(y) FROM trees WHERE map_id = $1 AND "
      "valid_to = " FORESTMAP_PG_CURRENT,
      Params().Int64(map_id));
  if (scan.IsNull(0, 0)) return std::nullopt;
  return Extent{scan.Double(0, 0), scan.Double(0, 1), scan.Double(0, 2), scan.Double(0, 3)};
}

std::vector<TreeRecord> ReadTreeRows(const pg::Result& result, const std::string& map_name) {
  std::vector<TreeRecord> trees(static_cast<size_t>(result.rows()));
  for (int r = 0; r < result.rows(); ++r) {
    TreeRecord& tree = trees[static_cast<size_t>(r)];
    tree.id = result.Int64(r, 0);
    tree.x = result.Double(r, 1);
    tree.y = result.Double(r, 2);
    tree.z = result.OptionalDouble(r, 3);
    tree.dbh = result.OptionalDouble(r, 4);
    if (!result.IsNull(r, 5)) internal::SetStoredAttributes(tree, result.Text(r, 5), map_name);
    tree.status = result.Int64(r, 6) == 0 ? TreeStatus::kCandidate : TreeStatus::kConfirmed;
    tree.observations = result.Int64(r, 7);
    tree.position_sigma = result.OptionalDouble(r, 8);
    tree.dbh_sigma = result.OptionalDouble(r, 9);
  }
  return trees;
}

void InsertTrees(pg::Connection& conn, const MapRow& map, const std::vector<TreeRecord>& trees,
                 const std::vector<int64_t>& ids, int64_t valid_from) {
  if (const std::optional<size_t> taken = FirstTakenId(conn, map.id, ids)) {
    throw StorageError(Code::kInvalidArgument, "map '" + map.info.name +
                                                   "': " + internal::TreeLabel(trees, *taken) +
                                                   ": tree id already exists in the map");
  }
  for (size_t begin = 0; begin < trees.size(); begin += PostgresMapStore::kRowsPerInsert) {
    const size_t end = std::min(trees.size(), begin + PostgresMapStore::kRowsPerInsert);
    TreeColumnArrays columns;
    for (size_t i = begin; i < end; ++i) {
      try {
        columns.Add(ids[i], trees[i]);
      } catch (const nlohmann::json::exception& e) {
        throw StorageError(Code::kInvalidArgument,
                           "map '" + map.info.name + "': " + internal::TreeLabel(trees, i) +
                               ": attributes are not valid UTF-8: " + e.what());
      }
    }
    Params params;
    params.Int64(map.id).Int64(valid_from);
    columns.AppendTo(params);
    conn.Exec(
        "INSERT INTO trees (map_id, valid_from, valid_to, tree_id, x, y, z, dbh, attributes, "
        "status, observations, position_sigma, dbh_sigma) SELECT $1, $2, " FORESTMAP_PG_CURRENT
        ", u.* FROM unnest($3::bigint[], $4::float8[], $5::float8[], $6::float8[], "
        "$7::float8[], $8::text[], $9::smallint[], $10::bigint[], $11::float8[], "
        "$12::float8[]) AS u",
        params);
  }
}

void TreeColumnArrays::Add(int64_t id, const TreeRecord& tree) {
  attributes_.OptionalText(EncodeAttributes(tree.attributes, tree.null_attributes));
  id_.Int64(id);
  x_.Double(tree.x);
  y_.Double(tree.y);
  z_.OptionalDouble(tree.z);
  dbh_.OptionalDouble(tree.dbh);
  status_.Int64(tree.status == TreeStatus::kConfirmed ? 1 : 0);
  observations_.Int64(tree.observations);
  position_sigma_.OptionalDouble(tree.position_sigma);
  dbh_sigma_.OptionalDouble(tree.dbh_sigma);
}

void TreeColumnArrays::AppendTo(Params& params) const {
  for (const pg::ArrayLiteral* array : {&id_, &x_, &y_, &z_, &dbh_, &attributes_, &status_,
                                        &observations_, &position_sigma_, &dbh_sigma_}) {
    params.Text(array->Finish());
  }
}

std::vector<TreeRecord> CurrentTreesInBox(pg::Connection& conn, const MapRow& map,
                                          const Extent& box) {
  const pg::Result result =
      conn.Exec("SELECT " FORESTMAP_PG_TREE_COLUMNS
                " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_PG_CURRENT
                " AND t.x >= $2 AND t.x <= $3 AND t.y >= $4 AND t.y <= $5 ORDER BY t.tree_id",
                Params().Int64(map.id).Double(box.min_x).Double(box.max_x).Double(box.min_y).Double(
                    box.max_y));
  return ReadTreeRows(result, map.info.name);
}

std::vector<ObservationRecord> ReadObservationRows(const pg::Result& result) {
  std::vector<ObservationRecord> rows(static_cast<size_t>(result.rows()));
  for (int r = 0; r < result.rows(); ++r) {
    ObservationRecord& o = rows[static_cast<size_t>(r)];
    o.id = result.Int64(r, 0);
    o.tree_id = result.Int64(r, 1);
    o.source = result.Text(r, 2);
    o.frame_id = result.Int64(r, 3);
    o.detection_index = static_cast<int32_t>(result.Int64(r, 4));
    o.x = result.Double(r, 5);
    o.y = result.Double(r, 6);
    o.z = result.OptionalDouble(r, 7);
    o.dbh = result.OptionalDouble(r, 8);
    o.weight_xy = result.Double(r, 9);
    o.weight_dbh = result.Double(r, 10);
    o.sensor_x = result.Double(r, 11);
    o.sensor_y = result.Double(r, 12);
    o.sensor_z = result.Double(r, 13);
    o.prior = result.Bool(r, 14);
    o.version = result.Int64(r, 15);
  }
  return rows;
}

void InsertObservations(pg::Connection& conn, int64_t map_id,
                        const std::vector<ObservationRecord>& observations, int64_t valid_from) {
  for (size_t begin = 0; begin < observations.size(); begin += PostgresMapStore::kRowsPerInsert) {
    const size_t end = std::min(observations.size(), begin + PostgresMapStore::kRowsPerInsert);
    constexpr int kColumns = 17;
    pg::ArrayLiteral arrays[kColumns];
    for (size_t i = begin; i < end; ++i) {
      const ObservationRecord& o = observations[i];
      const ObservationCell cell = CellOf(o.x, o.y);
      arrays[0].Int64(o.tree_id);
      arrays[1].Text(o.source);
      arrays[2].Int64(o.frame_id);
      arrays[3].Int64(o.detection_index);
      arrays[4].Double(o.x);
      arrays[5].Double(o.y);
      arrays[6].OptionalDouble(o.z);
      arrays[7].OptionalDouble(o.dbh);
      arrays[8].Double(o.weight_xy);
      arrays[9].Double(o.weight_dbh);
      arrays[10].Double(o.sensor_x);
      arrays[11].Double(o.sensor_y);
      arrays[12].Double(o.sensor_z);
      arrays[13].Text(o.prior ? "t" : "f");
      arrays[14].Int64(cell.x);
      arrays[15].Int64(cell.y);
      arrays[16].Int64(static_cast<int64_t>(i));  // keeps the ids in the order of the rows
    }
    Params params;
    params.Int64(map_id).Int64(valid_from);
    for (const pg::ArrayLiteral& array : arrays) params.Text(array.Finish());
    conn.Exec(
        "INSERT INTO observations (map_id, valid_from, valid_to, tree_id, source, frame_id, "
        "detection_index, x, y, z, dbh, weight_xy, weight_dbh, sensor_x, sensor_y, sensor_z, "
        "prior, cell_x, cell_y) SELECT $1, $2, " FORESTMAP_PG_CURRENT
        ", u.tree_id, u.source, u.frame_id, u.detection_index, u.x, u.y, u.z, u.dbh, "
        "u.weight_xy, u.weight_dbh, u.sensor_x, u.sensor_y, u.sensor_z, u.prior, u.cell_x, "
        "u.cell_y FROM unnest($3::bigint[], $4::text[], $5::bigint[], $6::integer[], "
        "$7::float8[], $8::float8[], $9::float8[], $10::float8[], $11::float8[], $12::float8[], "
        "$13::float8[], $14::float8[], $15::float8[], $16::boolean[], $17::bigint[], "
        "$18::bigint[], $19::bigint[]) AS u(tree_id, source, frame_id, detection_index, x, y, z, "
        "dbh, weight_xy, weight_dbh, sensor_x, sensor_y, sensor_z, prior, cell_x, cell_y, ord) "
        "ORDER BY u.ord",
        params);
  }
}

void InsertVersion(pg::Connection& conn, int64_t map_id, const VersionRecord& r) {
  Params params;
  params.Int64(map_id).Int64(r.version).Int64(r.created_unix_ms);
  params.Int64(static_cast<int64_t>(r.kind)).Text(r.source).Int64(r.tree_count);
  params.Int64(r.confirmed_count).Int64(r.trees_added).Int64(r.trees_updated);
  params.Int64(r.trees_removed).Int64(r.observations_added).Int64(r.observations_removed);
  params.Int64(r.restored_from);
  conn.Exec(
      "INSERT INTO map_versions (map_id, version, created_unix_ms, kind, source, tree_count, "
      "confirmed_count, trees_added, trees_updated, trees_removed, observations_added, "
      "observations_removed, restored_from) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, "
      "$11, $12, $13)",
      params);
}

VersionRecord RequireVersion(pg::Connection& conn, const MapRow& map, int64_t version) {
  const pg::Result select = conn.Exec(
      "SELECT version, created_unix_ms, kind, source, tree_count, confirmed_count, trees_added, "
      "trees_updated, trees_removed, observations_added, observations_removed, restored_from "
      "FROM map_versions WHERE map_id = $1 AND version = $2",
      Params().Int64(map.id).Int64(version));
  if (select.rows() == 0) {
    const pg::Result first = conn.Exec("SELECT MIN(version) FROM map_versions WHERE map_id = $1",
                                       Params().Int64(map.id));
    const int64_t oldest = first.IsNull(0, 0) ? map.info.version : first.Int64(0, 0);
    throw StorageError(Code::kNotFound, "map '" + map.info.name + "' has no version " +
                                            std::to_string(version) + "; versions " +
                                            std::to_string(oldest) + " to " +
                                            std::to_string(map.info.version) + " can be read");
  }
  VersionRecord r;
  r.version = select.Int64(0, 0);
  r.created_unix_ms = select.Int64(0, 1);
  r.kind = static_cast<VersionKind>(select.Int64(0, 2));
  r.source = select.Text(0, 3);
  r.tree_count = select.Int64(0, 4);
  r.confirmed_count = select.Int64(0, 5);
  r.trees_added = select.Int64(0, 6);
  r.trees_updated = select.Int64(0, 7);
  r.trees_removed = select.Int64(0, 8);
  r.observations_added = select.Int64(0, 9);
  r.observations_removed = select.Int64(0, 10);
  r.restored_from = select.Int64(0, 11);
  return r;
}

}  // namespace forestmap::storage::pg_internal
