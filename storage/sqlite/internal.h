#pragma once
// Pieces of SqliteMapStore shared by its source files (schema, rows, versions). Not a public API.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "storage/checks.h"
#include "storage/map_store.h"
#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "storage/store_steps.h"

namespace forestmap::storage::internal {

// valid_to of rows that belong to the current version ("forever"). The literal appears in SQL
// text too (kCurrent below), so that SQLite can use the partial indexes on current rows.
inline constexpr int64_t kForever = std::numeric_limits<int64_t>::max();
#define FORESTMAP_CURRENT "9223372036854775807"

// Schema steps for sqlite::MigrateSchema and per-connection settings.
const std::vector<const char*>& SchemaSteps();
void ConfigureConnection(sqlite::Database& db, const SqliteMapStoreOptions& options,
                         bool read_only);

// Throws kInvalidArgument for a database without a ForestMap schema (PRAGMA user_version 0)
// that already holds tables: another program's file, which migrating would change.
void RefuseForeignDatabase(sqlite::Database& db);

// Throws kReadOnly when `db` cannot be written: opened read-only by the OS, or a probe commit
// (rewriting PRAGMA user_version with its value) fails (storage/sqlite_faults.cc).
void RefuseReadOnlyDatabase(sqlite::Database& db);
// Throws kReadOnly for database `path` with the cause the file system tells and `detail`.
[[noreturn]] void ThrowReadOnly(const std::string& path, const std::string& detail);
// PRAGMA max_page_count for a size limit of `max_mib` MiB (0: none) on this connection.
void LimitDatabaseSize(sqlite::Database& db, int64_t max_mib);

struct MapRow {
  int64_t id = 0;
  MapInfo info;
};
// Columns of every maps query, in the order ReadMapRow expects.
#define FORESTMAP_MAP_COLUMNS                                                     \
  "id, name, description, crs, version, tree_count, min_x, min_y, max_x, max_y, " \
  "created_unix_ms, updated_unix_ms, confirmed_count"
MapRow ReadMapRow(const sqlite::Statement& row);
MapRow RequireMap(sqlite::Database& db, const std::string& name);  // kNotFound
// The history entry of `version`, or kNotFound naming the versions that can be read.
VersionRecord RequireVersion(sqlite::Database& db, const MapRow& map, int64_t version);
// Stores version, counts, extent and updated time of `map`.
void UpdateMapRow(sqlite::Database& db, const MapRow& map);

// Extent of the current trees, by a scan (after removals that may shrink it).
std::optional<Extent> ScanExtent(sqlite::Database& db, int64_t map_id);

// Tree columns of every tree query, in the order ReadTreeRow expects.
#define FORESTMAP_TREE_COLUMNS                                                                  \
  "t.tree_id, t.x, t.y, t.z, t.dbh, t.attributes, t.status, t.observations, t.position_sigma, " \
  "t.dbh_sigma"
TreeRecord ReadTreeRow(const sqlite::Statement& row, const std::string& map_name);

// Inserts trees[i] with id ids[i], valid from `valid_from` to `valid_to`, block by block with
// their R*Tree rows, in the returned order (consecutive rowids). A current id of the map ->
// kInvalidArgument naming the tree. Rows staged by an upload (sqlite_upload.cc) pass
// pending_base >= 0: a duplicate id among them throws StagedDuplicate (see InsertTree).
struct StagedDuplicate {
  size_t index;  // in `trees`
};
std::vector<size_t> InsertTrees(sqlite::Database& db, const MapRow& map,
                                const std::vector<TreeRecord>& trees,
                                const std::vector<int64_t>& ids, int64_t valid_from,
                                int64_t valid_to = kForever, int64_t pending_base = -1);
// Closes every current tree and observation row of a map at `version`; returns the number of
// observation rows closed.
int64_t CloseAllCurrentRows(sqlite::Database& db, int64_t map_id, int64_t version);
// Removes the staged rows (and the map it was creating) of every upload left by a process that
// stopped (sqlite_upload.cc); called when the store opens the database.
void RemoveAbandonedUploads(sqlite::Database& db);

// Uploads that create their map (schema step 7, sqlite_created_upload.cc): their trees are final
// rows of the hidden map, valid from kCreatedTreesVersion. Records where the rows of a chunk,
// from `first_rowid` on in `order` (InsertTrees), come from: the chunk starts at `first_index`.
inline constexpr int64_t kCreatedTreesVersion = 2;  // version 1: the map, created empty
void RecordChunk(sqlite::Database& db, int64_t upload_id, int64_t first_rowid, int64_t first_index,
                 const std::vector<size_t>& order);
// The index in the upload of its staged row with tree id `tree_id` in map `map_id` (unset: none).
std::optional<int64_t> StagedIndex(sqlite::Database& db, int64_t upload_id, int64_t map_id,
                                   int64_t tree_id);
// Removes the chunk records of `upload_id`, or with upload_id < 0 those of every upload that is
// no longer open.
void ForgetChunks(sqlite::Database& db, int64_t upload_id);
// Current trees of the map inside the box (inclusive), by id, through the spatial index.
std::vector<TreeRecord> CurrentTreesInBox(sqlite::Database& db, const MapRow& map,
                                          const Extent& box);

#define FORESTMAP_OBSERVATION_COLUMNS                                                \
  "o.id, o.tree_id, o.source, o.frame_id, o.detection_index, o.x, o.y, o.z, o.dbh, " \
  "o.weight_xy, o.weight_dbh, o.sensor_x, o.sensor_y, o.sensor_z, o.prior, o.valid_from"
ObservationRecord ReadObservationRow(const sqlite::Statement& row);
void InsertObservations(sqlite::Database& db, int64_t map_id,
                        const std::vector<ObservationRecord>& observations, int64_t valid_from);

// Commits a write transaction, honouring the thread's WriteRequest (storage/write_request.h):
// stores its answer under its id, refuses a passed deadline. `info`: the map after the write.
void CommitWrite(sqlite::Database& db, sqlite::Transaction& transaction, const MapInfo& info);

// Appends the history entry of `record.version`.
void InsertVersion(sqlite::Database& db, int64_t map_id, const VersionRecord& record);

}  // namespace forestmap::storage::internal
