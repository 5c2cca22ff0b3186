// The PostgreSQL schema of PostgresMapStore and its migrations.

#include <vector>

#include "storage/postgres/internal.h"

namespace forestmap::storage::pg {
namespace {

// Step i takes the schema from version i to i + 1 (pg::MigrateSchema). Never edit a shipped
// step: append one and bump PostgresMapStore::kSchemaVersion. The tables mirror the SQLite
// store's schema version 3 (storage/sqlite/schema.cc): rows carry [valid_from, valid_to), with
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

// Step 2: answers of writes made with a client request id (exactly-once writes),
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

// Step 3: what a stored request id is bound to (storage/write_request.h): the server's hash of the
// call, map, caller and request content; '' for answers stored before (bound to the call).
constexpr const char* kStep3 = R"sql(
ALTER TABLE request_log ADD COLUMN fingerprint TEXT NOT NULL DEFAULT '';
)sql";

// Step 4: survey boundaries (storage/boundary_json.h), as the SQLite store's schema version 10.
constexpr const char* kStep4 = R"sql(
CREATE TABLE map_boundaries (
  map_id BIGINT NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version BIGINT NOT NULL,
  polygons TEXT NOT NULL,  -- JSON: the coordinates of a GeoJSON MultiPolygon, map frame
  PRIMARY KEY (map_id, version)
);
)sql";

// Step 5: folded observation rows, as the SQLite store's schema version 11: a merge reads a
// tree's summary row and its rows not folded, never its folded rows.
constexpr const char* kStep5 = R"sql(
ALTER TABLE observations ADD COLUMN folded BOOLEAN NOT NULL DEFAULT false;
ALTER TABLE observations ADD COLUMN summary TEXT;  -- statistics of a summary row, else NULL
DROP INDEX observations_of_tree;
CREATE INDEX observations_of_tree ON observations (map_id, tree_id, folded)
  WHERE valid_to = 9223372036854775807;
DROP INDEX observations_in_cell;
CREATE INDEX observations_in_cell ON observations (map_id, cell_x, cell_y)
  WHERE valid_to = 9223372036854775807 AND NOT folded;
)sql";

// Step 6: the order of a map's attribute columns, as the SQLite store's schema version 12.
constexpr const char* kStep6 = R"sql(
CREATE TABLE map_columns (
  map_id BIGINT NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version BIGINT NOT NULL,
  names TEXT NOT NULL,  -- JSON: an array of attribute names
  PRIMARY KEY (map_id, version)
);
)sql";

// Step 7: the evidence of absence, as the SQLite store's schema version 13.
constexpr const char* kStep7 = R"sql(
ALTER TABLE trees ADD COLUMN last_seen_unix_ms BIGINT;
ALTER TABLE trees ADD COLUMN evidence TEXT;
DROP INDEX observations_of_source;
CREATE INDEX observations_of_source ON observations (map_id, source, cell_x, cell_y)
  WHERE valid_to = 9223372036854775807;
CREATE TABLE tree_removals (
  map_id BIGINT NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version BIGINT NOT NULL,  -- the version that removed the tree
  tree_id BIGINT NOT NULL,
  evidence TEXT NOT NULL,
  PRIMARY KEY (map_id, version, tree_id)
);
)sql";

}  // namespace

const std::vector<const char*>& SchemaSteps() {
  static const std::vector<const char*> steps = {kStep1, kStep2, kStep3, kStep4,
                                                 kStep5, kStep6, kStep7};
  return steps;
}

}  // namespace forestmap::storage::pg
