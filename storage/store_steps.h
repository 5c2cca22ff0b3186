#pragma once
// Steps of MapStore reads and writes that do not depend on the database: the bookkeeping of
// versions, counts and extents, id assignment and the checks of a page query. SqliteMapStore and
// PostgresMapStore both call them, so the two backends answer alike. Not a public API.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/checks.h"
#include "storage/map_store.h"
#include "storage/staged_writes.h"

namespace forestmap::storage::internal {

// ---- Time and extents ----

// ms since 1970, the clock of created_unix_ms / updated_unix_ms.
int64_t NowUnixMs();
// The smallest extent holding both (an unset one holds nothing).
std::optional<Extent> Union(const std::optional<Extent>& a, const std::optional<Extent>& b);

// ---- Rows ----

// Sets the survey columns of `tree` (of map `map_name`, id set) from their stored JSON `text`;
// kInternal naming the tree when the text is not a JSON object of strings and nulls.
void SetStoredAttributes(TreeRecord& tree, const std::string& text, const std::string& map_name);
// The survey columns of trees[index] as stored (EncodeAttributes); kInvalidArgument naming the
// tree of map `map_name` when they are not valid UTF-8.
std::optional<std::string> StoredAttributes(const std::string& map_name,
                                            const std::vector<TreeRecord>& trees, size_t index);

// ---- Versions ----

// A new map's info: version 1 without trees, created and updated now.
MapInfo NewMapInfo(const std::string& name, const std::string& description, const std::string& crs);
// The history entry of a map's creation (version 1, at `info`'s creation time).
VersionRecord CreationRecord(const MapInfo& info);
// kInvalidArgument for a negative version number (0 reads the current version).
void CheckVersionNumber(const std::string& name, int64_t version);
// The map as it was at `record.version`, whose trees were `trees`: the current map's name,
// description and CRS with that version's number, time, counts and extent.
MapInfo InfoAtVersion(MapInfo current, const VersionRecord& record,
                      const std::vector<TreeRecord>& trees);
// kConflict (stale) when `note` expects another version than `map`'s current one.
void CheckExpectedVersion(const MergeNote& note, const MapInfo& map);
// The history entry of the version a write of `kind` makes: the one after `map`'s.
VersionRecord NextVersion(const MapInfo& map, VersionKind kind, const std::string& source = {});
// Makes `info` the map at `record.version` with `extent`, updated now, and copies that time and
// the counts into `record`: the end of every write, before the map and history rows are stored.
void StampVersion(MapInfo& info, VersionRecord& record, std::optional<Extent> extent);
// StampVersion for restoring `old` as the version after `info`'s: counts of `old`, `extent`
// scanned after the restore.
void StampRestore(MapInfo& info, VersionRecord& record, const VersionRecord& old,
                  std::optional<Extent> extent);

// ---- Writing trees ----

// Whether WriteTrees of `trees` changes nothing (no version is made): nothing to append, or a
// replace of an empty map by nothing.
bool WriteChangesNothing(const std::vector<TreeRecord>& trees, bool replace, const MapInfo& map);
// The larger of an optional id and `id`.
std::optional<int64_t> MaxId(std::optional<int64_t> max_id, int64_t id);
// Ids of the batch in batch order: explicit ones, then the next free ones above `max_id` (and
// at least 1) for the `auto_count` trees without one. kInvalidArgument when they run out.
std::vector<int64_t> AssignIds(const std::string& map_name, const std::vector<TreeRecord>& trees,
                               std::optional<int64_t> max_id, size_t auto_count);
// Counts and extent of `info` after writing `trees` (summed up in `batch`), replacing the map's
// trees or adding to them; `record` gets trees_added, then StampVersion.
void StampWrittenBatch(MapInfo& info, VersionRecord& record, const std::vector<TreeRecord>& trees,
                       const BatchSummary& batch, bool replace);

// ---- Merges ----

// The trees a merge puts, counted into `info` (each as a new row: the caller subtracts the rows
// it closes): their ids in order and their extent.
struct PutTrees {
  std::vector<int64_t> ids;
  std::optional<Extent> extent;
};
PutTrees CountPutTrees(MapInfo& info, const std::vector<TreeRecord>& put_trees);
// kInvalidArgument for a merge's tree or observation to remove that is not current in the map.
StorageError TreeToRemoveMissing(const std::string& map_name, int64_t id);
StorageError ObservationToRemoveMissing(const std::string& map_name, int64_t id);
// Whether (x, y) lies on the border of `extent` (a closed row there may shrink it).
bool OnBorder(const std::optional<Extent>& extent, double x, double y);

// ---- Exactly-once writes ----

inline constexpr int64_t kRequestLogRetentionMs = 7 * 24 * 3600 * 1000LL;  // ms an answer is kept

// ---- Pages of an export ----

// kInvalidArgument for a version or limit below 1, or an invalid box.
void CheckPageQuery(const std::string& name, const TreePageQuery& query);
// kConflict when the map was created again since the export began, kNotFound for a version the
// map does not have yet.
void CheckPageTarget(const std::string& name, const TreePageQuery& query, const MapInfo& map);
// The box of a page query: its box, or the whole plane (infinite bounds) without one.
Extent PageBox(const TreePageQuery& query);
// The id a page's trees must exceed: after_id, or the lowest int64 without one.
int64_t PageAfterId(const TreePageQuery& query);
// Sorts a page read from current and closed rows by id and keeps the first `limit`.
void SortAndTrimPage(std::vector<TreeRecord>& trees, int64_t limit);

}  // namespace forestmap::storage::internal
