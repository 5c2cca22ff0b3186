// What `forestmap map changes` prints and writes (map_changes.h): the summary table, the JSON
// object, the rows of the GIS files and the CSV.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <string>

#include "client/cli/cli_format.h"
#include "client/cli/map_changes.h"

namespace forestmap::client {
namespace {

// The columns of every change, in order (x, y and id are the row's own).
constexpr const char* kColumns[] = {"dbh_before", "dbh_after", "dbh_change", "x_before", "y_before",
                                    "dx",         "dy",        "distance",   "threshold"};

// A number as the GIS writers type a Real field: 15 significant digits, or 17 where 15 do not
// read back as the same double.
std::string Number(double value) {
  char text[40];
  std::snprintf(text, sizeof(text), "%.15g", value);
  if (std::strtod(text, nullptr) != value) std::snprintf(text, sizeof(text), "%.17g", value);
  return text;
}

// A difference of two values, to a tenth of a millimetre (no 0.049999999 from the subtraction).
double Difference(double after, double before) { return std::round((after - before) * 1e4) / 1e4; }

// The values of kColumns for one change (m); unset where they do not apply.
std::vector<std::optional<double>> Values(const TreeChange& change) {
  std::vector<std::optional<double>> values(std::size(kColumns));
  const auto& before = change.before;
  const auto& after = change.after;
  if (before && before->dbh) values[0] = *before->dbh;
  if (after && after->dbh) values[1] = *after->dbh;
  if (before && after) {
    if (before->dbh && after->dbh) values[2] = Difference(*after->dbh, *before->dbh);
    values[3] = before->x;
    values[4] = before->y;
    values[5] = Difference(after->x, before->x);
    values[6] = Difference(after->y, before->y);
    values[7] = std::round(std::hypot(after->x - before->x, after->y - before->y) * 1e4) / 1e4;
  }
  if (change.kind == ChangeKind::kGrown || change.kind == ChangeKind::kMoved) {
    values[8] = std::round(change.threshold * 1e4) / 1e4;
  }
  return values;
}

const MapTreeRow& Place(const TreeChange& change) {
  return change.after ? *change.after : *change.before;
}

nlohmann::ordered_json VersionJson(const v1::MapVersion& version) {
  return {{"version", version.version()},
          {"created", FormatUnixMs(version.created_unix_ms())},
          {"created_unix_ms", version.created_unix_ms()}};
}

std::string ThresholdText(const std::optional<double>& fixed, double survey_sigma, double sigmas) {
  char text[200];
  if (fixed) {
    std::snprintf(text, sizeof(text), "more than %.1f mm (given)", *fixed * 1000);
  } else {
    std::snprintf(text, sizeof(text),
                  "more than %.4g sigma of the difference (each tree's sigma, else a survey "
                  "value's %.0f mm: %.0f mm for two survey values)",
                  sigmas, survey_sigma * 1000, sigmas * std::sqrt(2.0) * survey_sigma * 1000);
  }
  return text;
}

}  // namespace

void PrintChangesTable(const ChangesHeader& header, const MapChanges& changes, std::ostream& out) {
  out << "map '" << TerminalSafe(header.map) << "' (" << ListedCrs(header.crs) << ")\n"
      << "from version " << header.from.version() << " ("
      << FormatUnixMs(header.from.created_unix_ms()) << ", " << changes.trees_before << " trees)\n"
      << "to   version " << header.to.version() << " (" << FormatUnixMs(header.to.created_unix_ms())
      << ", " << changes.trees_after << " trees)\n";
  if (changes.candidates_before + changes.candidates_after > 0) {
    out << "candidates left out: " << changes.candidates_before << " and "
        << changes.candidates_after << " (--candidates compares them too)\n";
  }
  out << std::left << std::setw(10) << "CHANGE" << std::right << std::setw(8) << "TREES"
      << "\n";
  for (ChangeKind kind : kChangeKinds) {
    out << std::left << std::setw(10) << ChangeKindName(kind) << std::right << std::setw(8)
        << changes.Count(kind) << "\n";
  }
  out << "grown: DBH changed by "
      << ThresholdText(header.options.min_dbh_change, kSurveyDbhSigma, kDbhChangeSigmas) << "\n"
      << "moved: position changed by "
      << ThresholdText(header.options.min_move, kSurveyPositionSigma, kMoveSigmas) << "\n"
      << std::flush;
}

nlohmann::ordered_json ChangesJson(const ChangesHeader& header, const MapChanges& changes) {
  nlohmann::ordered_json json;
  json["map"] = header.map;
  json["crs"] = header.crs;
  json["from"] = VersionJson(header.from);
  json["to"] = VersionJson(header.to);
  json["trees_before"] = changes.trees_before;
  json["trees_after"] = changes.trees_after;
  json["candidates"] = header.options.candidates;
  nlohmann::ordered_json thresholds;
  thresholds["min_dbh_change"] = header.options.min_dbh_change
                                     ? nlohmann::ordered_json(*header.options.min_dbh_change)
                                     : nlohmann::ordered_json(nullptr);
  thresholds["min_move"] = header.options.min_move
                               ? nlohmann::ordered_json(*header.options.min_move)
                               : nlohmann::ordered_json(nullptr);
  thresholds["survey_dbh_sigma"] = kSurveyDbhSigma;
  thresholds["survey_position_sigma"] = kSurveyPositionSigma;
  json["thresholds"] = thresholds;
  nlohmann::ordered_json counts;
  for (ChangeKind kind : kChangeKinds) counts[ChangeKindName(kind)] = changes.Count(kind);
  json["counts"] = counts;
  json["changes"] = nlohmann::ordered_json::array();
  for (const TreeChange& change : changes.changes) {
    nlohmann::ordered_json item;
    item["id"] = change.id;
    item["change"] = ChangeKindName(change.kind);
    item["x"] = Place(change).x;
    item["y"] = Place(change).y;
    const std::vector<std::optional<double>> values = Values(change);
    for (size_t c = 0; c < values.size(); ++c) {
      item[kColumns[c]] =
          values[c] ? nlohmann::ordered_json(*values[c]) : nlohmann::ordered_json(nullptr);
    }
    json["changes"].push_back(item);
  }
  return json;
}

std::vector<MapTreeRow> ChangeRows(const std::vector<TreeChange>& changes) {
  std::vector<MapTreeRow> rows;
  rows.reserve(changes.size());
  for (const TreeChange& change : changes) {
    MapTreeRow row;
    const MapTreeRow& place = Place(change);
    row.id = change.id;
    row.x = place.x;
    row.y = place.y;
    row.z = place.z;
    row.dbh = place.dbh;
    row.attributes["change"] = ChangeKindName(change.kind);
    const std::vector<std::optional<double>> values = Values(change);
    for (size_t c = 0; c < values.size(); ++c) {
      if (values[c]) {
        row.attributes[kColumns[c]] = Number(*values[c]);
      } else {
        row.null_attributes.insert(kColumns[c]);
      }
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

void WriteChangesCsv(std::ostream& out, const std::vector<TreeChange>& changes) {
  out << "id,change,x,y";
  for (const char* column : kColumns) out << ',' << column;
  out << '\n';
  for (const TreeChange& change : changes) {
    out << change.id << ',' << ChangeKindName(change.kind) << ',' << Number(Place(change).x) << ','
        << Number(Place(change).y);
    for (const std::optional<double>& value : Values(change)) {
      out << ',' << (value ? Number(*value) : "");
    }
    out << '\n';
  }
}

}  // namespace forestmap::client
