// `forestmap map changes` without a server (client/cli/map_changes.h): the dates and versions
// --since and --to name, and two exports compared by tree id with thresholds from the trees'
// precision.

#include "client/cli/map_changes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "client/cli/cli_context.h"

namespace forestmap::client {
namespace {

constexpr int64_t kDay = 86'400'000;  // ms
// 2026-12-01T00:00:00Z
constexpr int64_t kDecember1 = 1'796'083'200'000;

TEST(ParseIsoTime, DatesAndTimesInUtcOrWithAnOffset) {
  EXPECT_EQ(ParseIsoTime("2026-12-01"), kDecember1);
  EXPECT_EQ(ParseIsoTime("2026-12-01T10:30"), kDecember1 + 37'800'000);
  EXPECT_EQ(ParseIsoTime("2026-12-01 10:30:15"), kDecember1 + 37'815'000);
  EXPECT_EQ(ParseIsoTime("2026-12-01T10:30:15Z"), kDecember1 + 37'815'000);
  EXPECT_EQ(ParseIsoTime("2026-12-01T10:30:15+02:00"), kDecember1 + 37'815'000 - 7'200'000);
  EXPECT_EQ(ParseIsoTime("2026-12-01T10:30-0500"), kDecember1 + 37'800'000 + 18'000'000);
  EXPECT_EQ(ParseIsoTime("2026-12-02"), kDecember1 + kDay);
  for (const char* bad :
       {"", "12", "2026-12", "2026-13-01", "2026-02-30", "2026-12-01T25:00", "2026-12-01T10",
        "2026-12-01T10:30+2", "2026-12-01X10:30", "yesterday", "2026-12-01T10:30:15 UTC"}) {
    EXPECT_FALSE(ParseIsoTime(bad)) << bad;
  }
}

v1::MapVersion Version(int64_t number, int64_t created_ms) {
  v1::MapVersion version;
  version.set_version(number);
  version.set_created_unix_ms(created_ms);
  return version;
}

std::string Refusal(const std::string& spec, const std::vector<v1::MapVersion>& versions) {
  try {
    ResolveVersion(spec, versions, "--since", "plot");
  } catch (const CommandError& error) {
    return error.what();
  }
  return "(no error)";
}

TEST(ResolveVersion, ANumberOrTheLastVersionMadeAtOrBeforeADate) {
  const std::vector<v1::MapVersion> history = {
      Version(1, kDecember1), Version(2, kDecember1 + 1000), Version(3, kDecember1 + 2 * kDay)};
  EXPECT_EQ(ResolveVersion("2", history, "--since", "plot").version(), 2);
  EXPECT_EQ(ResolveVersion("2026-12-01T00:00:01Z", history, "--since", "plot").version(), 2);
  EXPECT_EQ(ResolveVersion("2026-12-02", history, "--since", "plot").version(), 2);
  EXPECT_EQ(ResolveVersion("2026-12-03", history, "--since", "plot").version(), 3);
  EXPECT_EQ(Refusal("4", history),
            "--since 4: map 'plot' has versions 1..3 (see 'forestmap map "
            "history plot')");
  EXPECT_EQ(Refusal("2026-11-30", history),
            "--since 2026-11-30: map 'plot' did not exist yet: it was created at "
            "2026-12-01T00:00:00Z");
  // Pruned history: the versions before 2 are gone.
  const std::vector<v1::MapVersion> pruned(history.begin() + 1, history.end());
  EXPECT_EQ(Refusal("1", pruned),
            "--since 1: version 1 of map 'plot' was pruned; it keeps "
            "versions 2..3");
  EXPECT_EQ(Refusal("2026-11-30", pruned),
            "--since 2026-11-30: the history of map 'plot' before version 2 "
            "(2026-12-01T00:00:01Z) was pruned");
  EXPECT_EQ(Refusal("soon", history),
            "--since soon: expected a version number or a date (2026-12-01, "
            "2026-12-01T10:30:00Z)");
}

MapTreeRow Tree(int64_t id, double x, double y, std::optional<double> dbh) {
  MapTreeRow row;
  row.id = id;
  row.x = x;
  row.y = y;
  row.dbh = dbh;
  return row;
}

// A surveyed tree (no sigmas), or one observed by drones with its sigmas.
void Add(ExportedTrees& exported, const MapTreeRow& tree, TreeState state = {}) {
  exported.trees.push_back(tree);
  exported.states.push_back(state);
}

TreeState Observed(double position_sigma, double dbh_sigma, bool confirmed = true) {
  TreeState state;
  state.confirmed = confirmed;
  state.observations = 5;
  state.position_sigma_m = position_sigma;
  state.dbh_sigma_m = dbh_sigma;
  return state;
}

std::vector<std::pair<std::string, int64_t>> Kinds(const MapChanges& changes) {
  std::vector<std::pair<std::string, int64_t>> kinds;
  for (const TreeChange& change : changes.changes) {
    kinds.emplace_back(ChangeKindName(change.kind), change.id);
  }
  return kinds;
}

TEST(CompareExports, SurveyValuesChangeBeyondTheirPrecision) {
  ExportedTrees before, after;
  Add(before, Tree(1, 0, 0, 0.30));
  Add(before, Tree(2, 10, 0, 0.30));
  Add(before, Tree(3, 20, 0, 0.30));
  Add(before, Tree(4, 30, 0, std::nullopt));
  Add(after, Tree(1, 0, 0, 0.32));        // 2 cm: within 2 * hypot(1 cm, 1 cm) = 28 mm
  Add(after, Tree(2, 10, 0, 0.27));       // -3 cm: beyond (DBH changes either way)
  Add(after, Tree(3, 20.16, 0, 0.30));    // 16 cm: within 2.448 * hypot(5 cm, 5 cm) = 17.3 cm
  Add(after, Tree(4, 30.13, 0.13, 0.4));  // 18 cm: beyond; no DBH before, so not grown
  Add(after, Tree(5, 40, 0, 0.1));
  const MapChanges changes = CompareExports(before, after, {});
  EXPECT_EQ(Kinds(changes),
            (std::vector<std::pair<std::string, int64_t>>{{"new", 5}, {"grown", 2}, {"moved", 4}}));
  EXPECT_NEAR(changes.changes[1].threshold, 2 * std::hypot(0.01, 0.01), 1e-12);
  EXPECT_NEAR(changes.changes[2].threshold, 2.4477 * std::hypot(0.05, 0.05), 1e-12);
  EXPECT_EQ(changes.trees_before, 4);
  EXPECT_EQ(changes.trees_after, 5);
}

TEST(CompareExports, ObservedTreesUseTheirSigmasAndCandidatesAreLeftOutUnlessAsked) {
  ExportedTrees before, after;
  // Seen by many drones: 1 mm DBH sigma, 1 cm position sigma.
  Add(before, Tree(1, 0, 0, 0.300), Observed(0.01, 0.001));
  Add(after, Tree(1, 0.05, 0, 0.306), Observed(0.01, 0.001));
  Add(before, Tree(2, 10, 0, 0.2), Observed(0.2, 0.05, false));  // a candidate, gone later
  Add(after, Tree(3, 20, 0, 0.2), Observed(0.2, 0.05, false));   // a new candidate
  const MapChanges confirmed = CompareExports(before, after, {});
  EXPECT_EQ(Kinds(confirmed),
            (std::vector<std::pair<std::string, int64_t>>{{"grown", 1}, {"moved", 1}}));
  EXPECT_EQ(confirmed.candidates_before, 1);
  EXPECT_EQ(confirmed.candidates_after, 1);
  ChangeOptions with_candidates;
  with_candidates.candidates = true;
  EXPECT_EQ(Kinds(CompareExports(before, after, with_candidates)),
            (std::vector<std::pair<std::string, int64_t>>{
                {"removed", 2}, {"new", 3}, {"grown", 1}, {"moved", 1}}));
  // Fixed thresholds replace the sigmas.
  ChangeOptions fixed;
  fixed.min_dbh_change = 0.01;
  fixed.min_move = 0.1;
  EXPECT_TRUE(CompareExports(before, after, fixed).changes.empty());
}

TEST(ChangeRows, EveryRowHasEveryColumnValueOrNull) {
  ExportedTrees before, after;
  Add(before, Tree(1, 0, 0, 0.30));
  Add(before, Tree(2, 5, 5, 0.30));
  Add(after, Tree(1, 0.5, 0, 0.30));
  const MapChanges changes = CompareExports(before, after, {});
  const std::vector<MapTreeRow> rows = ChangeRows(changes.changes);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].attributes.at("change"), "removed");
  EXPECT_EQ(rows[0].x, 5);  // where the tree stood
  EXPECT_EQ(rows[0].attributes.size() + rows[0].null_attributes.size(),
            rows[1].attributes.size() + rows[1].null_attributes.size());
  EXPECT_EQ(rows[1].attributes.at("dx"), "0.5");
  EXPECT_EQ(rows[1].attributes.at("x_before"), "0");
  EXPECT_EQ(rows[1].null_attributes.count("dbh_change"), 0u);
  std::ostringstream csv;
  WriteChangesCsv(csv, changes.changes);
  EXPECT_EQ(csv.str(),
            "id,change,x,y,dbh_before,dbh_after,dbh_change,x_before,y_before,dx,dy,distance,"
            "threshold\n"
            "2,removed,5,5,0.3,,,,,,,,\n"
            "1,moved,0.5,0,0.3,0.3,0,0,0,0.5,0,0.5,0.1731\n");
}

}  // namespace
}  // namespace forestmap::client
