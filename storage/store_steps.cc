#include "storage/store_steps.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <nlohmann/json.hpp>
#include <utility>

#include "storage/attribute_json.h"

namespace forestmap::storage::internal {

using Code = StorageError::Code;

int64_t NowUnixMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::optional<Extent> Union(const std::optional<Extent>& a, const std::optional<Extent>& b) {
  if (!a) return b;
  if (!b) return a;
  return Extent{std::min(a->min_x, b->min_x), std::min(a->min_y, b->min_y),
                std::max(a->max_x, b->max_x), std::max(a->max_y, b->max_y)};
}

void SetStoredAttributes(TreeRecord& tree, const std::string& text, const std::string& map_name) {
  try {
    TreeAttributes stored = DecodeAttributes(text);
    tree.attributes = std::move(stored.values);
    tree.null_attributes = std::move(stored.nulls);
  } catch (const std::invalid_argument& e) {
    throw StorageError(Code::kInternal, "map '" + map_name + "' tree " + std::to_string(*tree.id) +
                                            ": stored attributes are not a JSON object of "
                                            "strings and nulls: " +
                                            e.what());
  }
}

std::optional<std::string> StoredAttributes(const std::string& map_name,
                                            const std::vector<TreeRecord>& trees, size_t index) {
  try {
    return EncodeAttributes(trees[index].attributes, trees[index].null_attributes);
  } catch (const nlohmann::json::exception& e) {
    throw StorageError(Code::kInvalidArgument, "map '" + map_name +
                                                   "': " + TreeLabel(trees, index) +
                                                   ": attributes are not valid UTF-8: " + e.what());
  }
}

MapInfo NewMapInfo(const std::string& name, const std::string& description,
                   const std::string& crs) {
  MapInfo info;
  info.name = name;
  info.description = description;
  info.crs = crs;
  info.version = 1;
  info.created_unix_ms = info.updated_unix_ms = NowUnixMs();
  return info;
}

VersionRecord CreationRecord(const MapInfo& info) {
  VersionRecord created;
  created.version = 1;
  created.created_unix_ms = info.created_unix_ms;
  created.kind = VersionKind::kCreate;
  return created;
}

void CheckVersionNumber(const std::string& name, int64_t version) {
  if (version < 0) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': version " + std::to_string(version) + " is negative");
  }
}

MapInfo InfoAtVersion(MapInfo current, const VersionRecord& record,
                      const std::vector<TreeRecord>& trees) {
  MapInfo info = std::move(current);
  info.version = record.version;
  info.updated_unix_ms = record.created_unix_ms;
  info.tree_count = static_cast<int64_t>(trees.size());
  info.confirmed_count = 0;
  info.extent.reset();
  for (const TreeRecord& tree : trees) {
    info.confirmed_count += tree.status == TreeStatus::kConfirmed ? 1 : 0;
    info.extent = Union(info.extent, Extent{tree.x, tree.y, tree.x, tree.y});
  }
  return info;
}

void CheckExpectedVersion(const MergeNote& note, const MapInfo& map) {
  if (note.expected_version && *note.expected_version != map.version) {
    throw StorageError(Code::kConflict,
                       "map '" + map.name + "' is at version " + std::to_string(map.version) +
                           ", not at the base version " + std::to_string(*note.expected_version) +
                           " (rejected as stale; fetch the map and retry, or merge anyway)");
  }
}

VersionRecord NextVersion(const MapInfo& map, VersionKind kind, const std::string& source) {
  VersionRecord record;
  record.version = map.version + 1;
  record.kind = kind;
  record.source = source;
  return record;
}

void StampVersion(MapInfo& info, VersionRecord& record, std::optional<Extent> extent) {
  info.extent = std::move(extent);
  info.version = record.version;
  info.updated_unix_ms = NowUnixMs();
  record.created_unix_ms = info.updated_unix_ms;
  record.tree_count = info.tree_count;
  record.confirmed_count = info.confirmed_count;
}

void StampRestore(MapInfo& info, VersionRecord& record, const VersionRecord& old,
                  std::optional<Extent> extent) {
  record.version = info.version + 1;
  record.kind = VersionKind::kRestore;
  record.restored_from = old.version;
  info.tree_count = old.tree_count;
  info.confirmed_count = old.confirmed_count;
  StampVersion(info, record, std::move(extent));
}

bool WriteChangesNothing(const std::vector<TreeRecord>& trees, bool replace, const MapInfo& map) {
  return trees.empty() && (!replace || map.tree_count == 0);
}

std::optional<int64_t> MaxId(std::optional<int64_t> max_id, int64_t id) {
  return std::max(max_id.value_or(std::numeric_limits<int64_t>::min()), id);
}

std::vector<int64_t> AssignIds(const std::string& map_name, const std::vector<TreeRecord>& trees,
                               std::optional<int64_t> max_id, size_t auto_count) {
  const int64_t above = std::max<int64_t>(max_id.value_or(0), 0);
  constexpr int64_t kMax = std::numeric_limits<int64_t>::max();
  if (auto_count > 0 && static_cast<uint64_t>(kMax - above) < auto_count) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + map_name + "': no free tree ids left above " +
                           std::to_string(above) + " for " + std::to_string(auto_count) +
                           " trees without an id");
  }
  std::vector<int64_t> ids(trees.size());
  int64_t assigned = 0;  // counted apart so the last id may be INT64_MAX without overflow
  for (size_t i = 0; i < trees.size(); ++i)
    ids[i] = trees[i].id ? *trees[i].id : above + ++assigned;
  return ids;
}

void StampWrittenBatch(MapInfo& info, VersionRecord& record, const std::vector<TreeRecord>& trees,
                       const BatchSummary& batch, bool replace) {
  // The new counts and extent follow from the old ones and the batch: no table scan needed.
  int64_t confirmed = 0;
  for (const TreeRecord& tree : trees) confirmed += tree.status == TreeStatus::kConfirmed;
  const auto count = static_cast<int64_t>(trees.size());
  info.tree_count = replace ? count : info.tree_count + count;
  info.confirmed_count = replace ? confirmed : info.confirmed_count + confirmed;
  record.trees_added = count;
  StampVersion(info, record, replace ? batch.extent : Union(info.extent, batch.extent));
}

PutTrees CountPutTrees(MapInfo& info, const std::vector<TreeRecord>& put_trees) {
  PutTrees put;
  put.ids.reserve(put_trees.size());
  for (const TreeRecord& tree : put_trees) {
    put.ids.push_back(*tree.id);
    info.tree_count += 1;
    info.confirmed_count += tree.status == TreeStatus::kConfirmed ? 1 : 0;
    put.extent = Union(put.extent, Extent{tree.x, tree.y, tree.x, tree.y});
  }
  return put;
}

StorageError TreeToRemoveMissing(const std::string& map_name, int64_t id) {
  return StorageError(
      Code::kInvalidArgument,
      "map '" + map_name + "': merge: tree " + std::to_string(id) + " to remove is not in the map");
}

StorageError ObservationToRemoveMissing(const std::string& map_name, int64_t id) {
  return StorageError(Code::kInvalidArgument, "map '" + map_name + "': merge: observation " +
                                                  std::to_string(id) +
                                                  " to remove is not current in the map");
}

bool OnBorder(const std::optional<Extent>& extent, double x, double y) {
  return extent &&
         (x == extent->min_x || x == extent->max_x || y == extent->min_y || y == extent->max_y);
}

void CheckPageQuery(const std::string& name, const TreePageQuery& query) {
  if (query.version < 1 || query.limit < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': a page needs version >= 1 and limit >= 1");
  }
  if (query.box) CheckBox(name, *query.box);
}

void CheckPageTarget(const std::string& name, const TreePageQuery& query, const MapInfo& map) {
  if (query.created_unix_ms != 0 && map.created_unix_ms != query.created_unix_ms) {
    throw StorageError(Code::kConflict, "map '" + name +
                                            "' was deleted and created again during the "
                                            "export; retry");
  }
  if (query.version > map.version) {
    throw StorageError(Code::kNotFound, "map '" + name + "' has no version " +
                                            std::to_string(query.version) + " yet");
  }
}

Extent PageBox(const TreePageQuery& query) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  return query.box ? *query.box : Extent{-kInf, -kInf, kInf, kInf};
}

int64_t PageAfterId(const TreePageQuery& query) {
  return query.after_id.value_or(std::numeric_limits<int64_t>::min());
}

void SortAndTrimPage(std::vector<TreeRecord>& trees, int64_t limit) {
  std::sort(trees.begin(), trees.end(),
            [](const TreeRecord& a, const TreeRecord& b) { return *a.id < *b.id; });
  if (static_cast<int64_t>(trees.size()) > limit) trees.resize(static_cast<size_t>(limit));
}

}  // namespace forestmap::storage::internal
