#pragma once
// Pieces of PostgresMapStore shared by its source files (schema, rows, versions). Not a public
// API. A new MapStore method goes into its own postgres_<topic>.cc using these helpers.

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "storage/map_store.h"
#include "storage/postgres/connection.h"
#include "storage/postgres/store.h"

namespace forestmap::storage::pg_internal {

// valid_to of current rows. Written as a literal in SQL so that PostgreSQL uses the partial
// indexes on current rows (a bound parameter would not match their predicate).
#define FORESTMAP_PG_CURRENT "9223372036854775807"

const std::vector<const char*>& SchemaSteps();

struct MapRow {
  int64_t id = 0;
  MapInfo info;
};
#define FORESTMAP_PG_MAP_COLUMNS                                                  \
  "id, name, description, crs, version, tree_count, min_x, min_y, max_x, max_y, " \
  "created_unix_ms, updated_unix_ms, confirmed_count"
MapRow ReadMapRow(const pg::Result& result, int row);
// kNotFound for an unknown map.
MapRow RequireMap(pg::Connection& conn, const std::string& name);
// For a write: takes the map's advisory lock (held to the end of the transaction), then reads
// its row, which no other writer can change until then. kNotFound for an unknown map.
MapRow LockMap(pg::Connection& conn, const std::string& name);
// Commits a write transaction honouring the thread's WriteRequest (storage/write_request.h):
// stores its answer under its id (hex text), refuses a passed deadline (postgres_requests.cc).
void CommitWrite(pg::Connection& conn, pg::Transaction& transaction, const MapInfo& info);
void UpdateMapRow(pg::Connection& conn, const MapRow& map);
std::optional<Extent> ScanExtent(pg::Connection& conn, int64_t map_id);

#define FORESTMAP_PG_TREE_COLUMNS                                                               \
  "t.tree_id, t.x, t.y, t.z, t.dbh, t.attributes, t.status, t.observations, t.position_sigma, " \
  "t.dbh_sigma"
std::vector<TreeRecord> ReadTreeRows(const pg::Result& result, const std::string& map_name);
// Inserts trees[i] with id ids[i], valid from `valid_from`. A current id of the map ->
// kInvalidArgument naming the tree.
void InsertTrees(pg::Connection& conn, const MapRow& map, const std::vector<TreeRecord>& trees,
                 const std::vector<int64_t>& ids, int64_t valid_from);
// The ten tree columns of an INSERT ... SELECT FROM unnest(...), one array literal each, in the
// order of FORESTMAP_PG_TREE_COLUMNS: tree_id, x, y, z, dbh, attributes, status, observations,
// position_sigma, dbh_sigma.
class TreeColumnArrays {
 public:
  // Appends a row. Attributes that are not valid UTF-8 throw nlohmann::json::exception: the
  // caller names the tree.
  void Add(int64_t id, const TreeRecord& tree);
  // The ten arrays as text parameters, in column order.
  void AppendTo(pg::Params& params) const;

 private:
  pg::ArrayLiteral id_, x_, y_, z_, dbh_, attributes_, status_, observations_, position_sigma_,
      dbh_sigma_;
};
// Current trees of the map inside the box (inclusive), by id.
std::vector<TreeRecord> CurrentTreesInBox(pg::Connection& conn, const MapRow& map,
                                          const Extent& box);

#define FORESTMAP_PG_OBSERVATION_COLUMNS                                             \
  "o.id, o.tree_id, o.source, o.frame_id, o.detection_index, o.x, o.y, o.z, o.dbh, " \
  "o.weight_xy, o.weight_dbh, o.sensor_x, o.sensor_y, o.sensor_z, o.prior, o.valid_from"
std::vector<ObservationRecord> ReadObservationRows(const pg::Result& result);
void InsertObservations(pg::Connection& conn, int64_t map_id,
                        const std::vector<ObservationRecord>& observations, int64_t valid_from);

void InsertVersion(pg::Connection& conn, int64_t map_id, const VersionRecord& record);
// The history entry of `version`, or kNotFound naming the versions that can be read.
VersionRecord RequireVersion(pg::Connection& conn, const MapRow& map, int64_t version);

std::string Int64Array(const std::vector<int64_t>& values);

}  // namespace forestmap::storage::pg_internal
