#pragma once
// Steps that do not depend on the database, shared by VersionedMapStore, the staged uploads and
// the backends' row code: the clock, extents, stored attributes, the bookkeeping of versions and
// counts, and the bounds of a page query. Not a public API.

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
// The history entry of the version a write of `kind` makes: the one after `map`'s.
VersionRecord NextVersion(const MapInfo& map, VersionKind kind, const std::string& source = {});
// Makes `info` the map at `record.version` with `extent`, updated now, and copies that time and
// the counts into `record`: the end of every write, before the map and history rows are stored.
void StampVersion(MapInfo& info, VersionRecord& record, std::optional<Extent> extent);

// ---- Writing trees ----

// Counts and extent of `info` after writing `count` trees (`confirmed` of them, inside `extent`),
// replacing the map's trees or adding to them; `record` (NextVersion's) gets trees_added and,
// for a replace, trees_removed, then StampVersion. The end of WriteTrees and of an upload.
void StampWrite(MapInfo& info, VersionRecord& record, int64_t count, int64_t confirmed,
                const std::optional<Extent>& extent, bool replace);

// ---- Exactly-once writes ----

inline constexpr int64_t kRequestLogRetentionMs = 7 * 24 * 3600 * 1000LL;  // ms an answer is kept

// ---- Pages of an export ----

// The box of a page query: its box, or the whole plane (infinite bounds) without one.
Extent PageBox(const TreePageQuery& query);
// The id a page's trees must exceed: after_id, or the lowest int64 without one.
int64_t PageAfterId(const TreePageQuery& query);

}  // namespace forestmap::storage::internal
