#pragma once
// Which header column is which tree column, for inventories as field crews and other tools
// deliver them (see tree_csv.h for the columns themselves).
//
// Resolution, per column of a map file's header:
// 1. By name, case-insensitively: x | x_m, y | y_m, z | z_m,
//    dbh | dbh_m | dbh_cm | dbh_mm | dbh_in, id | tree_id | treeid. These cover lidR (treeID, X, Y,
//    Z, DBH in m) and 3DFin (X, Y, Z, DBH in m) output.
// 2. Dialects, recognised by their header:
//    - FORTLS tree lists (a `h.dist` column): `tree` is the tree id, `dbh` is in cm, and `id`
//      (FORTLS's plot id) stays an attribute;
//    - TreeLoc++ tree states (TreeManagerState_N.csv: `location_x`, `location_y`): location_x,
//      location_y, location_z are x, y, z; `dbh` is in m and, where empty, `dbh_approximation`
//      stands in for it (as TreeLoc++ reads it); the rotation axis_00..axis_22, score,
//      reconstructed and number_clusters stay attributes;
//    - lidR locate_trees output (`treeID` and `Z`, no DBH column): Z is the tree-top height, so it
//      stays an attribute (and a point geometry's z is not read as the stem base).
//    3DFin's tree tables (X, Y, DBH in m, TH; a first column of T1, T2, ... without a name) need
//    nothing more than 1.
// 3. `--columns x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree` (any subset) names the columns
//    explicitly and wins over 1 and 2; a column that would otherwise have given the same tree
//    column is kept as an attribute. One header column named for two tree columns is refused.
// The DBH unit: --dbh-unit when given, else the column name's suffix (_cm, _mm, _in), else
// FORTLS's cm, else metres. A --dbh-unit that contradicts the suffix (dbh_cm with mm) is refused.

#include <map>
#include <optional>
#include <ostream>
#include <set>
#include <string>
#include <vector>

namespace forestmap::client {

struct MapTreeRow;  // tree_csv.h

enum class DbhUnit { kMetre, kCentimetre, kMillimetre, kInch };

struct TreeFileOptions {
  std::map<std::string, std::string> columns;  // tree column (x, y, z, dbh, id) -> header name
  std::optional<DbhUnit> dbh_unit;             // nullopt: from the header, else metres
  std::string columns_flag = "--columns";      // the flags that gave them, named in messages
  std::string dbh_unit_flag = "--dbh-unit";    // (compare's reference: --reference-*)
  std::ostream* notes = nullptr;  // where notes on the reading go (text ids); nullptr: nowhere
  std::string layer;              // GIS files: the layer to read; empty: the only one with points
};

// "x=Field_Xpj,y=Field_Ypj": throws std::invalid_argument naming `flag` and the bad entry.
std::map<std::string, std::string> ParseColumnMapping(const std::string& text,
                                                      const std::string& flag = "--columns");
// "m", "cm", "mm" or "in": throws std::invalid_argument naming `flag` otherwise.
DbhUnit ParseDbhUnit(const std::string& text, const std::string& flag = "--dbh-unit");
const char* DbhUnitName(DbhUnit unit);
double MetresPer(DbhUnit unit);  // 1, 0.01, 0.001 or 0.0254

// The resolved header of a map file.
struct ResolvedColumns {
  std::vector<std::string> canonical;  // per header column: x, y, z, dbh, id or another name
  DbhUnit dbh_unit = DbhUnit::kMetre;
  std::optional<size_t> dbh_fallback;  // column read (same unit) where dbh is unknown: TreeLoc++
  bool z_is_tree_height = false;       // lidR tree tops: a point geometry's z is no stem base
};

// Throws CsvError "FILE:LINE: --columns dbh=DBHX: no column 'DBHX' (columns: a,b,c)".
ResolvedColumns ResolveMapColumns(const std::vector<std::string>& header,
                                  const TreeFileOptions& options, const std::string& where);

// The attribute columns of an export (CSV and GIS files): each attribute (or null attribute) of
// any row, with the name it is written under; those named in `order` (the survey file's column
// order, MapSnapshot::attribute_columns) first, in that order, then the others in name order. Names
// that would read back as a tree column (X_m, treeID, dbh_cm, location_x, Z, ...) or switch a
// dialect on (h.dist) are written as "attr_NAME", so that reading the file back keeps the tree
// columns and the DBH unit, and the value stays an attribute; so are the lower-case names in
// `also_reserved` (a format's own columns: GeoPackage's fid and geom). Two attributes that would
// be written under one name (compared case-insensitively, as GeoPackage does: Species and
// species) are not: the later one is written as attr_NAME (or NAME_2, ...).
struct ExportedAttribute {
  std::string name;    // the attribute's name
  std::string column;  // the column it is written as
};
std::vector<ExportedAttribute> ExportedAttributes(const std::vector<MapTreeRow>& rows,
                                                  const std::set<std::string>& also_reserved = {},
                                                  const std::vector<std::string>& order = {});

// The attribute columns of a file read into `rows`: the names of `header` (its columns or fields,
// in file order) that are an attribute or null attribute of some row.
std::vector<std::string> AttributeColumnOrder(const std::vector<std::string>& header,
                                              const std::vector<MapTreeRow>& rows);

// A DBH column whose median (in metres, after the unit) is over 3 m holds centimetres or
// millimetres read as metres (a 14.9 cm stem read as 14.9 m), one under 1 cm holds metres read
// as cm or mm (a 0.3 m stem read as 3 mm): throws CsvError naming the file, column and unit.
void CheckDbhMedian(const std::vector<MapTreeRow>& rows, const std::string& file,
                    const std::string& column, DbhUnit unit);

}  // namespace forestmap::client
