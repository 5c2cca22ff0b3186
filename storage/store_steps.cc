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

void StampWrite(MapInfo& info, VersionRecord& record, int64_t count, int64_t confirmed,
                const std::optional<Extent>& extent, bool replace) {
  // The new counts and extent follow from the old ones and the batch: no table scan needed.
  record.trees_added = count;
  if (replace) record.trees_removed = info.tree_count;
  info.tree_count = replace ? count : info.tree_count + count;
  info.confirmed_count = replace ? confirmed : info.confirmed_count + confirmed;
  StampVersion(info, record, replace ? extent : Union(info.extent, extent));
}

Extent PageBox(const TreePageQuery& query) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  return query.box ? *query.box : Extent{-kInf, -kInf, kInf, kInf};
}

int64_t PageAfterId(const TreePageQuery& query) {
  return query.after_id.value_or(std::numeric_limits<int64_t>::min());
}

}  // namespace forestmap::storage::internal
