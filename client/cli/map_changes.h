#pragma once
// What changed in a map between two of its versions (`forestmap map changes`, cli_map_changes.cc),
// kept apart from the command so that it can be tested without a server: the versions a
// --since / --to names, the comparison of two exports by tree id, and what the command prints and
// writes.
//
// Kinds of change, by tree id: `removed` (in the older version only), `new` (in the newer only),
// `grown` (DBH known in both and changed, either way, by more than the tree's threshold) and
// `moved` (position changed by more than the tree's threshold). A tree both grown and moved is
// one change of each kind.
//
// Thresholds come from the precision of the two values compared. A tree's sigma is the export's
// (dbh_sigma_m, position_sigma_m: trees observed by drones), else that of a survey value, the one
// the server gives a surveyed tree when drones first observe it: 1 cm DBH and 5 cm position
// (1-sigma per axis; algorithms/merging/map_merge.h MergeOptions). A change counts when it is
// beyond what two independent values of those sigmas give 19 times in 20: the DBH difference
// beyond 2 sigma of the difference (two survey values: 2 * hypot(1 cm, 1 cm) = 28 mm); the
// horizontal distance beyond the 95% quantile of its Rayleigh law, 2.448 sigma of the difference
// per axis (two survey values: 17 cm). Versions of one tree share observations, so the
// difference varies less than that and the thresholds err on the side of no change. Fixed
// thresholds (--min-dbh-change, --min-move) replace them.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "client/lib/forestmap_client.h"

namespace forestmap::client {

// A survey value's precision (1-sigma), when the export gives a tree none.
constexpr double kSurveyDbhSigma = 0.01;       // m
constexpr double kSurveyPositionSigma = 0.05;  // m, per axis
constexpr double kDbhChangeSigmas = 2.0;       // two-sided 95% of a normal difference
constexpr double kMoveSigmas = 2.4477;         // sqrt(-2 ln 0.05): 95% of a Rayleigh distance

// "2026-12-01" (00:00 UTC that day), "2026-12-01T10:30", "2026-12-01 10:30:15",
// "2026-12-01T10:30:15Z" or with an offset "+02:00" / "-0500": milliseconds since 1970 UTC
// (a time without a zone is UTC, as `map history` prints). nullopt when `text` is none of these.
std::optional<int64_t> ParseIsoTime(const std::string& text);

// The version --since or --to (`flag`) names among `versions` (ListVersions: the readable
// versions of map `name`, oldest first): a version number, or a date: the last version made at
// or before it. Throws CommandError saying why there is none (a version not yet made or pruned,
// a date before the map existed or before the oldest version kept, neither a number nor a date).
const v1::MapVersion& ResolveVersion(const std::string& spec,
                                     const std::vector<v1::MapVersion>& versions,
                                     const std::string& flag, const std::string& name);

enum class ChangeKind { kRemoved, kNew, kGrown, kMoved };
constexpr ChangeKind kChangeKinds[] = {ChangeKind::kRemoved, ChangeKind::kNew, ChangeKind::kGrown,
                                       ChangeKind::kMoved};
const char* ChangeKindName(ChangeKind kind);  // "removed", "new", "grown", "moved"

struct ChangeOptions {
  std::optional<double> min_dbh_change;  // m; unset: from the trees' sigmas (above)
  std::optional<double> min_move;        // m; unset: from the trees' sigmas (above)
  bool candidates = false;               // compare candidate trees too (default: confirmed only)
};

struct TreeChange {
  ChangeKind kind = ChangeKind::kNew;
  int64_t id = 0;
  std::optional<MapTreeRow> before, after;  // the tree in each version (one of them for
                                            // removed / new)
  double threshold = 0;                     // m, grown / moved: what the change had to exceed
};

struct MapChanges {
  std::vector<TreeChange> changes;                      // by kind (kChangeKinds' order), then id
  int64_t trees_before = 0, trees_after = 0;            // trees compared in each version
  int64_t candidates_before = 0, candidates_after = 0;  // candidates left out
  int Count(ChangeKind kind) const;
};

MapChanges CompareExports(const ExportedTrees& before, const ExportedTrees& after,
                          const ChangeOptions& options);

// What the report says besides the changes.
struct ChangesHeader {
  std::string map, crs;
  v1::MapVersion from, to;
  ChangeOptions options;
};

// The terminal summary: the versions and dates compared, trees in each, a count per kind and
// the thresholds.
void PrintChangesTable(const ChangesHeader& header, const MapChanges& changes, std::ostream& out);

// --json: one object {map, crs, from, to, trees_before, trees_after, thresholds, counts, changes}.
nlohmann::ordered_json ChangesJson(const ChangesHeader& header, const MapChanges& changes);

// The changes as tree rows for the GIS writers (geo_io.h): the point where the tree stands (its
// old place for removed trees), id, dbh (the newer value, the older for removed trees) and the
// attributes change, dbh_before, dbh_after, dbh_change, x_before, y_before, dx, dy, distance,
// threshold (metres; null where they do not apply).
std::vector<MapTreeRow> ChangeRows(const std::vector<TreeChange>& changes);

// --out FILE.csv: a header and one line per change, the ChangeRows columns:
// id,change,x,y,dbh_before,dbh_after,dbh_change,x_before,y_before,dx,dy,distance,threshold.
void WriteChangesCsv(std::ostream& out, const std::vector<TreeChange>& changes);

}  // namespace forestmap::client
