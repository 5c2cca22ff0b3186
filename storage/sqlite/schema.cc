// The SQLite schema of SqliteMapStore and its migrations.

#include <string>
#include <vector>

#include "storage/sqlite/internal.h"

namespace forestmap::storage::sqlite {
namespace {

// Step i takes a database from user_version i to i + 1 (see sqlite::MigrateSchema). Never edit a
// shipped step: append a new one and bump SqliteMapStore::kSchemaVersion.
//
// tree_blocks is the spatial index: one R*Tree row per block of trees of one map that were
// written together and lie close together; the block's trees occupy the rowids first_rowid ..
// last_rowid of `trees`. map_id is an index dimension so a box query on one map does not wade
// through other maps in the same frame, and an auxiliary column for exact matching (the R*Tree
// keeps 32-bit floats, rounded outwards: it answers a superset that queries filter exactly).
// ON DELETE CASCADE does not reach a virtual table: whoever deletes trees deletes their blocks.
constexpr const char* kStep1 = R"sql(
CREATE TABLE maps (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  description TEXT NOT NULL,
  crs TEXT NOT NULL,
  version INTEGER NOT NULL,
  tree_count INTEGER NOT NULL,
  min_x REAL, min_y REAL, max_x REAL, max_y REAL,  -- NULL for an empty map
  created_unix_ms INTEGER NOT NULL,
  updated_unix_ms INTEGER NOT NULL
);
CREATE TABLE trees (
  rowid INTEGER PRIMARY KEY,
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  tree_id INTEGER NOT NULL,
  x REAL NOT NULL,
  y REAL NOT NULL,
  z REAL,
  dbh REAL,
  attributes TEXT,  -- JSON object of strings, NULL when there are none
  UNIQUE (map_id, tree_id)
);
CREATE VIRTUAL TABLE tree_blocks USING rtree(
  id, min_map, max_map, min_x, max_x, min_y, max_y, +map_id, +first_rowid, +last_rowid);
PRAGMA user_version = 1;
)sql";

// Version 2, shared maps: every version stays readable. A tree row holds one state of one tree
// for the versions valid_from <= v < valid_to (valid_to = 2^63-1 while current); a change closes
// the current row and inserts a new one, so the blocks of tree_blocks (rowid ranges) stay valid
// and old rows simply stop matching "current". Observation rows are versioned the same way, and
// map_versions is the history. Existing trees are kept (rowids too) as rows of the map's current
// version, which becomes the first version of its history (kind 7, "migrated").
constexpr const char* kStep2 = R"sql(
CREATE TABLE trees_v2 (
  rowid INTEGER PRIMARY KEY,
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  tree_id INTEGER NOT NULL,
  valid_from INTEGER NOT NULL,  -- first map version holding this row
  valid_to INTEGER NOT NULL,    -- first map version no longer holding it; 2^63-1 while current
  x REAL NOT NULL,
  y REAL NOT NULL,
  z REAL,
  dbh REAL,
  attributes TEXT,  -- JSON object of strings, NULL when there are none
  status INTEGER NOT NULL DEFAULT 1,  -- 0 candidate, 1 confirmed
  observations INTEGER NOT NULL DEFAULT 0,
  position_sigma REAL,  -- m
  dbh_sigma REAL        -- m
);
INSERT INTO trees_v2 (rowid, map_id, tree_id, valid_from, valid_to, x, y, z, dbh, attributes)
  SELECT t.rowid, t.map_id, t.tree_id, m.version, 9223372036854775807, t.x, t.y, t.z, t.dbh,
         t.attributes
  FROM trees AS t JOIN maps AS m ON m.id = t.map_id;
DROP TABLE trees;
ALTER TABLE trees_v2 RENAME TO trees;
CREATE UNIQUE INDEX trees_current ON trees (map_id, tree_id)
  WHERE valid_to = 9223372036854775807;
-- Closed rows only: a write of current rows (a survey upload) maintains one index, as before.
CREATE INDEX trees_history ON trees (map_id, tree_id, valid_from)
  WHERE valid_to != 9223372036854775807;

CREATE TABLE observations (
  id INTEGER PRIMARY KEY,
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  tree_id INTEGER NOT NULL,
  valid_from INTEGER NOT NULL,
  valid_to INTEGER NOT NULL,
  source TEXT NOT NULL,
  frame_id INTEGER NOT NULL,
  detection_index INTEGER NOT NULL,
  x REAL NOT NULL,
  y REAL NOT NULL,
  z REAL,
  dbh REAL,
  weight_xy REAL NOT NULL,   -- 1/m^2
  weight_dbh REAL NOT NULL,  -- 1/m^2
  sensor_x REAL NOT NULL,
  sensor_y REAL NOT NULL,
  sensor_z REAL NOT NULL,
  prior INTEGER NOT NULL     -- 1 for a survey prior
);
CREATE INDEX observations_of_tree ON observations (map_id, tree_id)
  WHERE valid_to = 9223372036854775807;
CREATE INDEX observations_of_source ON observations (map_id, source)
  WHERE valid_to = 9223372036854775807;
CREATE INDEX observations_history ON observations (map_id, valid_from)
  WHERE valid_to != 9223372036854775807;

CREATE TABLE map_versions (
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version INTEGER NOT NULL,
  created_unix_ms INTEGER NOT NULL,
  kind INTEGER NOT NULL,  -- storage::VersionKind
  source TEXT NOT NULL,
  tree_count INTEGER NOT NULL,
  confirmed_count INTEGER NOT NULL,
  trees_added INTEGER NOT NULL,
  trees_updated INTEGER NOT NULL,
  trees_removed INTEGER NOT NULL,
  observations_added INTEGER NOT NULL,
  observations_removed INTEGER NOT NULL,
  restored_from INTEGER NOT NULL,
  PRIMARY KEY (map_id, version)
) WITHOUT ROWID;
ALTER TABLE maps ADD COLUMN confirmed_count INTEGER NOT NULL DEFAULT 0;
UPDATE maps SET confirmed_count = tree_count;
INSERT INTO map_versions
  SELECT id, version, updated_unix_ms, 7, '', tree_count, tree_count, 0, 0, 0, 0, 0, 0 FROM maps;
PRAGMA user_version = 2;
)sql";

// Version 3: current observation rows are found by cell (storage::ObservationCell, 4 m squares),
// so that a merge can load the rows around its frames, and the rows linked to those, without
// going through their trees. The cell is floor(coordinate / 4) (CAST truncates toward zero).
constexpr const char* kStep3 = R"sql(
ALTER TABLE observations ADD COLUMN cell_x INTEGER NOT NULL DEFAULT 0;
ALTER TABLE observations ADD COLUMN cell_y INTEGER NOT NULL DEFAULT 0;
UPDATE observations SET
  cell_x = CAST(x / 4.0 AS INTEGER) - (x / 4.0 < CAST(x / 4.0 AS INTEGER)),
  cell_y = CAST(y / 4.0 AS INTEGER) - (y / 4.0 < CAST(y / 4.0 AS INTEGER));
CREATE INDEX observations_in_cell ON observations (map_id, cell_x, cell_y)
  WHERE valid_to = 9223372036854775807;
PRAGMA user_version = 3;
)sql";

// Version 4: the answers of writes made with a client request id (exactly-once writes,
// storage/write_request.h), kept for kRequestLogRetentionMs.
constexpr const char* kStep4 = R"sql(
CREATE TABLE request_log (
  request_id TEXT PRIMARY KEY,
  rpc TEXT NOT NULL,
  response BLOB NOT NULL,
  created_unix_ms INTEGER NOT NULL
);
CREATE INDEX request_log_by_time ON request_log (created_unix_ms);
PRAGMA user_version = 4;
)sql";

// Version 5: access tokens of the server (storage/token_store.h). Only the SHA-256 of a token's
// secret is stored; a revoked token keeps its row, so the server stays closed (deny by default)
// once any token has been created.
constexpr const char* kStep5 = R"sql(
CREATE TABLE access_tokens (
  id INTEGER PRIMARY KEY,
  secret_sha256 TEXT NOT NULL UNIQUE,  -- lowercase hex of SHA-256(secret)
  map_pattern TEXT NOT NULL,           -- a map name or a glob ('*': every map)
  role INTEGER NOT NULL,               -- storage::Role: 1 read, 2 write, 3 admin
  note TEXT NOT NULL,
  created_unix_ms INTEGER NOT NULL,
  revoked_unix_ms INTEGER              -- NULL while valid
);
PRAGMA user_version = 5;
)sql";

// Version 6: uploads staged in the database (storage/sqlite/upload.cc). An upload's trees are
// written in short transactions as pending rows of `trees`: valid_to = -(upload id), so no read
// sees them (every query asks for valid_to = 2^63-1 or valid_to > a version), and valid_from =
// the tree's index in the upload (for error messages). Its commit turns them current in one
// UPDATE. trees_pending keeps ids unique within an upload. A map created by an upload exists
// hidden (creating_upload set) until the upload commits.
constexpr const char* kStep6 = R"sql(
CREATE TABLE uploads (
  id INTEGER PRIMARY KEY,
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  creates_map INTEGER NOT NULL,  -- 1: the map row is this upload's, hidden until it commits
  first_rowid INTEGER,           -- rowids of trees holding its pending rows (NULL: none yet)
  last_rowid INTEGER,
  started_unix_ms INTEGER NOT NULL
);
ALTER TABLE maps ADD COLUMN creating_upload INTEGER;  -- NULL once the map exists
CREATE UNIQUE INDEX trees_pending ON trees (valid_to, tree_id) WHERE valid_to < 0;
PRAGMA user_version = 6;
)sql";

// Version 7: an upload that creates its map (storage/sqlite/created_upload.cc) writes its trees
// as the final rows of the hidden map (valid_from 2, valid_to current), so its commit changes a
// few rows whatever its size: the map row is revealed. Its chunks are written in packing order;
// upload_chunks keeps, per chunk, the index in the upload of each row (to name the earlier tree
// of a duplicate id). Rows of a committed upload are removed after the commit.
constexpr const char* kStep7 = R"sql(
CREATE TABLE upload_chunks (
  upload_id INTEGER NOT NULL,    -- uploads.id (no foreign key: removed after the commit)
  first_rowid INTEGER NOT NULL,  -- rowid of the chunk's first tree row; its rows are consecutive
  first_index INTEGER NOT NULL,  -- index in the upload of the chunk's first tree
  packing BLOB NOT NULL,         -- per row in rowid order, its index in the chunk (int32 LE)
  PRIMARY KEY (upload_id, first_rowid)
);
PRAGMA user_version = 7;
)sql";

// Version 8: what a stored request id is bound to (storage/write_request.h): the server's hash of
// the call, map, caller and request content; '' for answers stored before (bound to the call).
constexpr const char* kStep8 = R"sql(
ALTER TABLE request_log ADD COLUMN fingerprint TEXT NOT NULL DEFAULT '';
PRAGMA user_version = 8;
)sql";

// Version 9: tokens may expire (storage/token_store.h); NULL: never.
constexpr const char* kStep9 = R"sql(
ALTER TABLE access_tokens ADD COLUMN expires_unix_ms INTEGER;
PRAGMA user_version = 9;
)sql";

// Version 10: survey boundaries (storage/boundary_json.h). A row holds the map's boundary from
// `version` on, until the next row of the map; polygons '' removed it.
constexpr const char* kStep10 = R"sql(
CREATE TABLE map_boundaries (
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version INTEGER NOT NULL,
  polygons TEXT NOT NULL,  -- JSON: the coordinates of a GeoJSON MultiPolygon, map frame
  PRIMARY KEY (map_id, version)
) WITHOUT ROWID;
PRAGMA user_version = 10;
)sql";

// Version 11: folded observation rows (storage::ObservationRecord::folded, summary). A merge
// reads a tree's summary row and its rows not folded, never its folded rows: the indexes by tree
// and by cell leave folded rows out of what a merge reads (by tree they are found apart, for a
// source removal). Existing rows are not folded (their trees fold when a merge next rebuilds them).
constexpr const char* kStep11 = R"sql(
ALTER TABLE observations ADD COLUMN folded INTEGER NOT NULL DEFAULT 0;
ALTER TABLE observations ADD COLUMN summary TEXT;  -- statistics of a summary row, else NULL
DROP INDEX observations_of_tree;
CREATE INDEX observations_of_tree ON observations (map_id, tree_id, folded)
  WHERE valid_to = 9223372036854775807;
DROP INDEX observations_in_cell;
CREATE INDEX observations_in_cell ON observations (map_id, cell_x, cell_y)
  WHERE valid_to = 9223372036854775807 AND folded = 0;
PRAGMA user_version = 11;
)sql";

// Version 12: the order of a map's attribute columns (the survey file's order, which exports keep;
// storage/attribute_json.h). A row holds the order from `version` on, until the next row of the
// map. A map without a row (all maps of version 11) exports its attributes in name order.
constexpr const char* kStep12 = R"sql(
CREATE TABLE map_columns (
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version INTEGER NOT NULL,
  names TEXT NOT NULL,  -- JSON: an array of attribute names
  PRIMARY KEY (map_id, version)
) WITHOUT ROWID;
PRAGMA user_version = 12;
)sql";

// Version 13: the evidence of absence of a tree (storage::TreeRecord::last_seen_unix_ms and
// evidence), and the trees removed by it, with their evidence (storage::TreeRemoval); the rows of
// a source found by their cells too (MergeReader::ObservationsOfSourceIn).
constexpr const char* kStep13 = R"sql(
ALTER TABLE trees ADD COLUMN last_seen_unix_ms INTEGER;
ALTER TABLE trees ADD COLUMN evidence TEXT;
DROP INDEX observations_of_source;
CREATE INDEX observations_of_source ON observations (map_id, source, cell_x, cell_y)
  WHERE valid_to = 9223372036854775807;
CREATE TABLE tree_removals (
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  version INTEGER NOT NULL,  -- the version that removed the tree
  tree_id INTEGER NOT NULL,
  evidence TEXT NOT NULL,
  PRIMARY KEY (map_id, version, tree_id)
) WITHOUT ROWID;
PRAGMA user_version = 13;
)sql";

}  // namespace

const std::vector<const char*>& SchemaSteps() {
  static const std::vector<const char*> steps = {kStep1,  kStep2,  kStep3, kStep4, kStep5,
                                                 kStep6,  kStep7,  kStep8, kStep9, kStep10,
                                                 kStep11, kStep12, kStep13};
  return steps;
}

void ConfigureConnection(Database& db, const SqliteMapStoreOptions& options, bool read_only) {
  // synchronous = NORMAL is durable against application crashes in WAL mode; a power loss may
  // only drop the last commits, never corrupt the file.
  db.Execute("PRAGMA foreign_keys = ON; PRAGMA synchronous = NORMAL");
  // PRAGMA values cannot be bound; this one is an integer from checked options, not user text.
  // A negative cache_size is in KiB.
  const std::string cache_sql = "PRAGMA cache_size = -" + std::to_string(options.cache_mib * 1024);
  db.Execute(cache_sql.c_str());
  if (read_only) db.Execute("PRAGMA query_only = ON");
  LimitDatabaseSize(db, options.max_db_mib);
}

void RefuseForeignDatabase(Database& db) {
  if (db.QueryInt64("PRAGMA user_version") != 0) return;
  Statement tables(db,
                   "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT LIKE "
                   "'sqlite_%' ORDER BY name LIMIT 5");
  std::string names;
  while (tables.Step()) names += (names.empty() ? "" : ", ") + tables.ColumnText(0);
  if (names.empty()) return;  // a new, empty file: ours to initialise
  throw StorageError(StorageError::Code::kInvalidArgument,
                     "database '" + db.path() + "' is not a ForestMap database (it holds tables " +
                         names +
                         " and no ForestMap schema); refusing to change it: give "
                         "forestmapd a new file or a ForestMap database");
}

}  // namespace forestmap::storage::sqlite
