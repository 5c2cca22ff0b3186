#include "client/io/tree_columns.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <map>
#include <set>
#include <stdexcept>

#include "client/io/csv_columns.h"
#include "client/io/csv_reader.h"
#include "client/io/str_cat.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {
namespace {

constexpr double kMaxMedianDbh = 3.0;   // m: no tree is that thick
constexpr double kMinMedianDbh = 0.01;  // m: a stand of stems under 1 cm is no inventory
constexpr double kMetresPerInch = 0.0254;
constexpr const char* kTreeColumns[] = {"x", "y", "z", "dbh", "id"};

std::string Lower(std::string_view text) {
  std::string out(Trim(text));
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

bool IsTreeColumn(const std::string& name) {
  return std::find(std::begin(kTreeColumns), std::end(kTreeColumns), name) !=
         std::end(kTreeColumns);
}

// A name no header column canonicalises to: the column is kept as an attribute.
std::string AsAttribute(const std::string& header_name) { return "attribute:" + header_name; }

std::string HeaderList(const std::vector<std::string>& header) {
  std::string names;
  for (const std::string& name : header) names += (names.empty() ? "" : ",") + name;
  return names;
}

}  // namespace

std::map<std::string, std::string> ParseColumnMapping(const std::string& text,
                                                      const std::string& flag) {
  std::map<std::string, std::string> mapping;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(',', start), text.size());
    const std::string entry(Trim(std::string_view(text).substr(start, end - start)));
    const size_t equals = entry.find('=');
    if (equals == std::string::npos) {
      throw std::invalid_argument(flag + ": '" + entry +
                                  "' is not COLUMN=HEADER (e.g. x=Field_Xpj,dbh=DBH)");
    }
    const std::string column = Lower(entry.substr(0, equals));
    const std::string header(Trim(std::string_view(entry).substr(equals + 1)));
    if (!IsTreeColumn(column)) {
      throw std::invalid_argument(flag + ": '" + column +
                                  "' is not a tree column (x, y, z, dbh, id)");
    }
    if (header.empty()) throw std::invalid_argument(flag + ": " + column + "= names no column");
    for (const auto& [other, other_header] : mapping) {
      if (Lower(other_header) == Lower(header)) {
        throw std::invalid_argument(flag + ": the column '" + header + "' is mapped twice (" +
                                    other + "=" + other_header + " and " + column + "=" + header +
                                    "): each tree column needs its own");
      }
    }
    if (!mapping.emplace(column, header).second) {
      throw std::invalid_argument(flag + ": '" + column + "' is given twice");
    }
    start = end + 1;
  }
  return mapping;
}

DbhUnit ParseDbhUnit(const std::string& text, const std::string& flag) {
  const std::string unit = Lower(text);
  if (unit == "m") return DbhUnit::kMetre;
  if (unit == "cm") return DbhUnit::kCentimetre;
  if (unit == "mm") return DbhUnit::kMillimetre;
  if (unit == "in") return DbhUnit::kInch;
  throw std::invalid_argument(flag + ": '" + text + "' is not one of m, cm, mm, in");
}

const char* DbhUnitName(DbhUnit unit) {
  switch (unit) {
    case DbhUnit::kCentimetre:
      return "cm";
    case DbhUnit::kMillimetre:
      return "mm";
    case DbhUnit::kInch:
      return "in";
    default:
      return "m";
  }
}

double MetresPer(DbhUnit unit) {
  switch (unit) {
    case DbhUnit::kCentimetre:
      return 0.01;
    case DbhUnit::kMillimetre:
      return 0.001;
    case DbhUnit::kInch:
      return kMetresPerInch;
    default:
      return 1.0;
  }
}

namespace {

// The tools whose column names differ from ours (see tree_columns.h), told apart by the header.
struct Dialect {
  bool fortls = false;     // FORTLS tree list: has h.dist
  bool treeloc = false;    // TreeLoc++ tree state: has location_x and location_y
  bool tree_tops = false;  // lidR locate_trees: treeID and Z, no DBH column: Z is the tree height

  explicit Dialect(const std::vector<std::string>& header) {
    const auto has = [&](std::string_view name) {
      return std::any_of(header.begin(), header.end(),
                         [&](const std::string& h) { return Lower(h) == name; });
    };
    fortls = has("h.dist");
    treeloc = has("location_x") && has("location_y");
    const bool dbh = std::any_of(header.begin(), header.end(), [](const std::string& h) {
      const std::string lower = Lower(h);
      return lower.starts_with("dbh") || lower == "diameter";
    });
    tree_tops = has("treeid") && has("z") && !dbh;
  }

  std::string Canonical(const std::string& name) const {
    const std::string lower = Lower(name);
    if (lower == "treeid") return "id";
    if (lower == "dbh_cm" || lower == "dbh_mm" || lower == "dbh_in") return "dbh";
    if (fortls && lower == "id") return AsAttribute(name);
    if (fortls && lower == "tree") return "id";
    if (treeloc && lower.starts_with("location_") && lower.size() == 10) {
      const std::string axis = lower.substr(9);  // location_x, location_y, location_z
      if (axis == "x" || axis == "y" || axis == "z") return axis;
    }
    if (tree_tops && lower == "z") return AsAttribute(name);
    return CanonicalColumnName(name);
  }
};

}  // namespace

namespace {

// --dbh-unit, else the unit the DBH column's name (_cm, _mm, _in) or dialect implies, else m;
// a --dbh-unit contradicting the name's unit is refused.
DbhUnit DbhUnitOf(const std::vector<std::string>& header, const std::vector<std::string>& canonical,
                  const TreeFileOptions& options, const std::string& where, bool fortls) {
  std::optional<DbhUnit> name_unit;  // said by the column's name
  std::optional<DbhUnit> header_unit;
  std::string column;
  for (size_t i = 0; i < header.size(); ++i) {
    if (canonical[i] != "dbh") continue;
    column = header[i];
    const std::string lower = Lower(header[i]);
    if (lower.ends_with("_cm")) name_unit = DbhUnit::kCentimetre;
    if (lower.ends_with("_mm")) name_unit = DbhUnit::kMillimetre;
    if (lower.ends_with("_in")) name_unit = DbhUnit::kInch;
    if (lower.ends_with("_m")) name_unit = DbhUnit::kMetre;
    header_unit = name_unit;
    if (fortls && lower == "dbh") header_unit = DbhUnit::kCentimetre;
  }
  if (options.dbh_unit && name_unit && *options.dbh_unit != *name_unit) {
    throw CsvError(StrCat({where, ": column '", column, "' is in ", DbhUnitName(*name_unit),
                           " by its name, but ", options.dbh_unit_flag, " says ",
                           DbhUnitName(*options.dbh_unit), ": drop ", options.dbh_unit_flag,
                           " or rename the column"}));
  }
  return options.dbh_unit.value_or(header_unit.value_or(DbhUnit::kMetre));
}

}  // namespace

ResolvedColumns ResolveMapColumns(const std::vector<std::string>& header,
                                  const TreeFileOptions& options, const std::string& where) {
  ResolvedColumns resolved;
  const Dialect dialect(header);
  const bool fortls = dialect.fortls;
  resolved.z_is_tree_height = dialect.tree_tops && !options.columns.count("z");
  for (size_t i = 0; i < header.size(); ++i) {
    resolved.canonical.push_back(dialect.Canonical(header[i]));
    if (dialect.treeloc && Lower(header[i]) == "dbh_approximation") resolved.dbh_fallback = i;
  }
  for (const auto& [column, header_name] : options.columns) {
    const std::string wanted = Lower(header_name);
    const auto it = std::find_if(header.begin(), header.end(),
                                 [&](const std::string& h) { return Lower(h) == wanted; });
    if (it == header.end()) {
      throw CsvError(
          StrCat({where, ": ", options.columns_flag, " ", column, "=", header_name, ": no column '",
                  header_name, "' (columns: ", HeaderList(header), ")"}));
    }
    for (size_t i = 0; i < header.size(); ++i) {
      if (resolved.canonical[i] == column) resolved.canonical[i] = AsAttribute(header[i]);
    }
    resolved.canonical[it - header.begin()] = column;
  }
  resolved.dbh_unit = DbhUnitOf(header, resolved.canonical, options, where, fortls);
  return resolved;
}

namespace {

constexpr const char* kExportPrefix = "attr_";  // short: shapefile fields have 10 characters

// Lower-case names a reader takes as a tree column or a dialect's marker (see Dialect).
bool ReservedOnExport(const std::string& name) {
  static const std::set<std::string> kReserved = {
      "id",     "x",      "y",      "z",          "dbh",        "x_m",
      "y_m",    "z_m",    "dbh_m",  "tree_id",    "treeid",     "dbh_cm",
      "dbh_mm", "dbh_in", "h.dist", "location_x", "location_y", "location_z"};
  const std::string lower = Lower(name);
  return lower.empty() || kReserved.count(lower) != 0 || CanonicalColumnName(name).empty();
}

}  // namespace

namespace {

std::set<std::string> AttributeNames(const std::vector<MapTreeRow>& rows) {
  std::set<std::string> names;
  for (const MapTreeRow& row : rows) {
    for (const auto& [name, value] : row.attributes) names.insert(name);
    names.insert(row.null_attributes.begin(), row.null_attributes.end());
  }
  return names;
}

}  // namespace

std::vector<std::string> AttributeColumnOrder(const std::vector<std::string>& header,
                                              const std::vector<MapTreeRow>& rows) {
  const std::set<std::string> present = AttributeNames(rows);
  std::vector<std::string> order;
  for (const std::string& name : header) {
    if (present.count(name) != 0 && std::find(order.begin(), order.end(), name) == order.end()) {
      order.push_back(name);
    }
  }
  return order;
}

std::vector<ExportedAttribute> ExportedAttributes(const std::vector<MapTreeRow>& rows,
                                                  const std::set<std::string>& also_reserved,
                                                  const std::vector<std::string>& order) {
  std::set<std::string> unordered = AttributeNames(rows);
  std::vector<std::string> names;
  for (const std::string& name : order) {
    if (unordered.erase(name) != 0) names.push_back(name);
  }
  names.insert(names.end(), unordered.begin(), unordered.end());
  std::vector<ExportedAttribute> exported;
  std::set<std::string> taken;   // lower-case columns (GeoPackage compares them so)
  std::vector<size_t> clashing;  // attributes whose column another one took first
  for (const std::string& name : names) {
    const bool reserved = ReservedOnExport(name) || also_reserved.count(Lower(name)) != 0;
    exported.push_back({name, reserved ? kExportPrefix + name : name});
    if (!taken.insert(Lower(exported.back().column)).second)
      clashing.push_back(exported.size() - 1);
  }
  // Species and species: the second is written as attr_species (or species_2, ...), a column no
  // other attribute has, so that every map exports.
  for (const size_t i : clashing) {
    std::string column = kExportPrefix + exported[i].name;
    for (int n = 2; taken.count(Lower(column)) != 0 || ReservedOnExport(column); ++n) {
      column = exported[i].name + "_" + std::to_string(n);
    }
    taken.insert(Lower(column));
    exported[i].column = column;
  }
  return exported;
}

void CheckDbhMedian(const std::vector<MapTreeRow>& rows, const std::string& file,
                    const std::string& column, DbhUnit unit) {
  std::vector<double> dbh;
  for (const MapTreeRow& row : rows) {
    if (row.dbh) dbh.push_back(*row.dbh);
  }
  if (dbh.empty()) return;
  std::nth_element(dbh.begin(), dbh.begin() + dbh.size() / 2, dbh.end());
  const double median = dbh[dbh.size() / 2];
  char text[64];
  std::snprintf(text, sizeof(text), "%.4g", median);
  if (median > 0 && median < kMinMedianDbh) {
    throw CsvError(StrCat({file, ": column '", column, "': the median DBH is ", text, " m read in ",
                           DbhUnitName(unit),
                           " (under 1 cm: no inventory of trees); if the column is in metres, "
                           "drop --dbh-unit or give --dbh-unit m"}));
  }
  if (median <= kMaxMedianDbh) return;
  throw CsvError(StrCat({file, ": column '", column, "': the median DBH is ", text, " m read in ",
                         DbhUnitName(unit),
                         " (over 3 m: no tree is that thick); if the column is in centimetres, "
                         "add --dbh-unit cm (or mm for millimetres)"}));
}

}  // namespace forestmap::client
