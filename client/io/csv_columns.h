#pragma once
// Columns found by name and typed field parsing for the tree CSV files (see tree_csv.h).

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "client/io/csv_reader.h"

namespace forestmap::client {

// The name a header maps to: lower case, trimmed, with the aliases x_m, y_m, z_m, dbh_m and
// tree_id folded into x, y, z, dbh and id.
std::string CanonicalColumnName(std::string_view header_name);

// Where each known column is in a header.
class ColumnMap {
 public:
  // Throws CsvError at the header line when two columns give the same known column
  // ("columns 'x' and 'X_m' both give 'x'") or two other columns have the same name.
  ColumnMap(const CsvReader& reader, std::initializer_list<const char*> known);
  // As above with the known name of each header column given (io/tree_columns.h resolves them).
  ColumnMap(const CsvReader& reader, std::initializer_list<const char*> known,
            const std::vector<std::string>& canonical_names);

  // The column giving `canonical`, if any.
  std::optional<size_t> Find(std::string_view canonical) const;
  // As Find, but throws "FILE:LINE: missing required column 'y' (columns: a,b,c)".
  size_t Require(std::string_view canonical) const;
  // Columns that are not known and have a non-empty name, in header order.
  std::vector<size_t> OtherNamedColumns() const;

 private:
  const CsvReader& reader_;
  std::vector<std::string> known_;
  std::vector<size_t> index_;  // per known_ entry; header().size() when absent
};

// Empty, NA or NaN (any case): an unknown value.
bool IsMissing(const CsvField& field);

// Typed fields of the reader's current record; each throws CsvError naming line and column.
double RequiredNumber(const CsvReader& reader, size_t column);                 // finite
std::optional<double> OptionalNumber(const CsvReader& reader, size_t column);  // finite or unknown
std::optional<double> OptionalDiameter(const CsvReader& reader, size_t column);  // also >= 0
int64_t RequiredInteger(const CsvReader& reader, size_t column);

// `s` without leading and trailing white space.
std::string_view Trim(std::string_view s);

}  // namespace forestmap::client
