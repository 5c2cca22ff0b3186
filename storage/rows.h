#pragma once
// The rows of maps, trees, observations and history entries as both databases hold them: the
// columns their queries select and the order of the values their statements write, each written
// here once. Templates over a backend's view of a row, so that they inline into the loops over
// rows (reading a million trees costs what hand-written reads cost):
//   Row (a result row, columns from 0): IsNull(c), Int64(c), Double(c), OptionalDouble(c),
//       Text(c), Bool(c);
//   Out (the values of a statement, in order): Int64(v), OptionalInt64(v), Double(v),
//       OptionalDouble(v), Text(v), OptionalText(v), Bool(v).
// Not a public API.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "storage/map_store.h"
#include "storage/store_backend.h"
#include "storage/store_steps.h"

namespace forestmap::storage::internal {

// valid_to of rows that belong to the current version ("forever"). The literal is in the SQL text
// as well (FORESTMAP_CURRENT), so that both databases use their partial indexes on current rows:
// a bound parameter would not match the indexes' predicate.
inline constexpr int64_t kForever = std::numeric_limits<int64_t>::max();
#define FORESTMAP_CURRENT "9223372036854775807"

// ---- Maps ----

// The last: whether the newest boundary row of the map (that of its current version) holds one.
#define FORESTMAP_MAP_COLUMNS                                                             \
  "id, name, description, crs, version, tree_count, min_x, min_y, max_x, max_y, "         \
  "created_unix_ms, updated_unix_ms, confirmed_count, COALESCE((SELECT b.polygons <> '' " \
  "FROM map_boundaries AS b WHERE b.map_id = maps.id ORDER BY b.version DESC LIMIT 1), 0 = 1)"
template <typename Row>
MapRow ReadMapRow(const Row& row) {
  MapRow map;
  map.id = row.Int64(0);
  map.info.name = row.Text(1);
  map.info.description = row.Text(2);
  map.info.crs = row.Text(3);
  map.info.version = row.Int64(4);
  map.info.tree_count = row.Int64(5);
  if (!row.IsNull(6)) {
    map.info.extent = Extent{row.Double(6), row.Double(7), row.Double(8), row.Double(9)};
  }
  map.info.created_unix_ms = row.Int64(10);
  map.info.updated_unix_ms = row.Int64(11);
  map.info.confirmed_count = row.Int64(12);
  map.info.has_boundary = row.Bool(13);
  return map;
}

// What a change stores in the map's row: version, tree_count, min_x, min_y, max_x, max_y,
// updated_unix_ms, confirmed_count.
template <typename Out>
void WriteMapValues(Out& out, const MapInfo& info) {
  const auto bound = [&](double Extent::*field) -> std::optional<double> {
    if (!info.extent) return std::nullopt;
    return (*info.extent).*field;
  };
  out.Int64(info.version);
  out.Int64(info.tree_count);
  out.OptionalDouble(bound(&Extent::min_x));
  out.OptionalDouble(bound(&Extent::min_y));
  out.OptionalDouble(bound(&Extent::max_x));
  out.OptionalDouble(bound(&Extent::max_y));
  out.Int64(info.updated_unix_ms);
  out.Int64(info.confirmed_count);
}

// ---- Trees ----

// Columns of every tree query (table alias t), in the order of ReadTreeRow and WriteTreeValues.
#define FORESTMAP_TREE_COLUMNS                                                                  \
  "t.tree_id, t.x, t.y, t.z, t.dbh, t.attributes, t.status, t.observations, t.position_sigma, " \
  "t.dbh_sigma, t.last_seen_unix_ms, t.evidence"
template <typename Row>
TreeRecord ReadTreeRow(const Row& row, const std::string& map_name) {
  TreeRecord tree;
  tree.id = row.Int64(0);
  tree.x = row.Double(1);
  tree.y = row.Double(2);
  tree.z = row.OptionalDouble(3);
  tree.dbh = row.OptionalDouble(4);
  if (!row.IsNull(5)) SetStoredAttributes(tree, row.Text(5), map_name);
  tree.status = row.Int64(6) == 0 ? TreeStatus::kCandidate : TreeStatus::kConfirmed;
  tree.observations = row.Int64(7);
  tree.position_sigma = row.OptionalDouble(8);
  tree.dbh_sigma = row.OptionalDouble(9);
  if (!row.IsNull(10)) tree.last_seen_unix_ms = row.Int64(10);
  if (!row.IsNull(11)) tree.evidence = row.Text(11);
  return tree;
}

// `attributes`: the tree's survey columns as stored (EncodeStoredAttributes).
template <typename Out>
void WriteTreeValues(Out& out, int64_t id, const TreeRecord& tree,
                     const std::optional<std::string>& attributes) {
  out.Int64(id);
  out.Double(tree.x);
  out.Double(tree.y);
  out.OptionalDouble(tree.z);
  out.OptionalDouble(tree.dbh);
  out.OptionalText(attributes);
  out.Int64(tree.status == TreeStatus::kConfirmed ? 1 : 0);
  out.Int64(tree.observations);
  out.OptionalDouble(tree.position_sigma);
  out.OptionalDouble(tree.dbh_sigma);
  out.OptionalInt64(tree.last_seen_unix_ms);
  out.OptionalText(tree.evidence);
}

// ---- Observations ----

// Columns of every observation query (table alias o), in the order of ReadObservationRow.
#define FORESTMAP_OBSERVATION_COLUMNS                                                      \
  "o.id, o.tree_id, o.source, o.frame_id, o.detection_index, o.x, o.y, o.z, o.dbh, "       \
  "o.weight_xy, o.weight_dbh, o.sensor_x, o.sensor_y, o.sensor_z, o.prior, o.valid_from, " \
  "o.folded, o.summary"
template <typename Row>
ObservationRecord ReadObservationRow(const Row& row) {
  ObservationRecord o;
  o.id = row.Int64(0);
  o.tree_id = row.Int64(1);
  o.source = row.Text(2);
  o.frame_id = row.Int64(3);
  o.detection_index = static_cast<int32_t>(row.Int64(4));
  o.x = row.Double(5);
  o.y = row.Double(6);
  o.z = row.OptionalDouble(7);
  o.dbh = row.OptionalDouble(8);
  o.weight_xy = row.Double(9);
  o.weight_dbh = row.Double(10);
  o.sensor_x = row.Double(11);
  o.sensor_y = row.Double(12);
  o.sensor_z = row.Double(13);
  o.prior = row.Bool(14);
  o.version = row.Int64(15);
  o.folded = row.Bool(16);
  if (!row.IsNull(17)) o.summary = row.Text(17);
  return o;
}

// The values of an inserted row: tree_id, source, frame_id, detection_index, x, y, z, dbh,
// weight_xy, weight_dbh, sensor_x, sensor_y, sensor_z, prior, cell_x, cell_y (CellOf(x, y)),
// folded, summary.
template <typename Out>
void WriteObservationValues(Out& out, const ObservationRecord& o) {
  const ObservationCell cell = CellOf(o.x, o.y);
  out.Int64(o.tree_id);
  out.Text(o.source);
  out.Int64(o.frame_id);
  out.Int64(o.detection_index);
  out.Double(o.x);
  out.Double(o.y);
  out.OptionalDouble(o.z);
  out.OptionalDouble(o.dbh);
  out.Double(o.weight_xy);
  out.Double(o.weight_dbh);
  out.Double(o.sensor_x);
  out.Double(o.sensor_y);
  out.Double(o.sensor_z);
  out.Bool(o.prior);
  out.Int64(cell.x);
  out.Int64(cell.y);
  out.Bool(o.folded);
  out.OptionalText(o.summary);
}

// ---- History ----

#define FORESTMAP_VERSION_COLUMNS                                                      \
  "version, created_unix_ms, kind, source, tree_count, confirmed_count, trees_added, " \
  "trees_updated, trees_removed, observations_added, observations_removed, restored_from"
template <typename Row>
VersionRecord ReadVersionRow(const Row& row) {
  VersionRecord r;
  r.version = row.Int64(0);
  r.created_unix_ms = row.Int64(1);
  r.kind = static_cast<VersionKind>(row.Int64(2));
  r.source = row.Text(3);
  r.tree_count = row.Int64(4);
  r.confirmed_count = row.Int64(5);
  r.trees_added = row.Int64(6);
  r.trees_updated = row.Int64(7);
  r.trees_removed = row.Int64(8);
  r.observations_added = row.Int64(9);
  r.observations_removed = row.Int64(10);
  r.restored_from = row.Int64(11);
  return r;
}

// The values of FORESTMAP_VERSION_COLUMNS, in order.
template <typename Out>
void WriteVersionValues(Out& out, const VersionRecord& r) {
  out.Int64(r.version);
  out.Int64(r.created_unix_ms);
  out.Int64(static_cast<int64_t>(r.kind));
  out.Text(r.source);
  out.Int64(r.tree_count);
  out.Int64(r.confirmed_count);
  out.Int64(r.trees_added);
  out.Int64(r.trees_updated);
  out.Int64(r.trees_removed);
  out.Int64(r.observations_added);
  out.Int64(r.observations_removed);
  out.Int64(r.restored_from);
}

}  // namespace forestmap::storage::internal
