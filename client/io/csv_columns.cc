#include "client/io/csv_columns.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <set>

namespace forestmap::client {
namespace {

bool EqualsIgnoreCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

std::string Quoted(std::string_view text) {
  // Built by appending: GCC 12 warns falsely (-Wrestrict) about "'" + std::string + "'".
  std::string quoted;
  quoted.reserve(text.size() + 2);
  quoted.append(1, '\'').append(text).append(1, '\'');
  return quoted;
}

// from_chars does not take a leading '+', which some exports write.
std::string_view WithoutPlus(std::string_view text) {
  if (text.size() > 1 && text[0] == '+' && text[1] != '-') text.remove_prefix(1);
  return text;
}

double ParseFinite(const CsvReader& reader, size_t column) {
  const std::string_view raw = reader.fields()[column].text;
  const std::string_view text = WithoutPlus(raw);
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) reader.FailAt(column, Quoted(raw) + " is out of range");
  if (ec != std::errc() || end != text.data() + text.size()) {
    reader.FailAt(column, Quoted(raw) + " is not a number");
  }
  if (!std::isfinite(value)) reader.FailAt(column, Quoted(raw) + " is not a finite number");
  return value;
}

int64_t ParseInteger(const CsvReader& reader, size_t column) {
  const std::string_view raw = reader.fields()[column].text;
  const std::string_view text = WithoutPlus(raw);
  int64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) reader.FailAt(column, Quoted(raw) + " is out of range");
  if (ec != std::errc() || end != text.data() + text.size()) {
    reader.FailAt(column, Quoted(raw) + " is not an integer");
  }
  return value;
}

}  // namespace

std::string CanonicalColumnName(std::string_view header_name) {
  std::string name(Trim(header_name));
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (name == "x_m") return "x";
  if (name == "y_m") return "y";
  if (name == "z_m") return "z";
  if (name == "dbh_m") return "dbh";
  if (name == "tree_id") return "id";
  return name;
}

ColumnMap::ColumnMap(const CsvReader& reader, std::initializer_list<const char*> known)
    : ColumnMap(reader, known, [&reader] {
        std::vector<std::string> names;
        for (const std::string& name : reader.header()) names.push_back(CanonicalColumnName(name));
        return names;
      }()) {}

ColumnMap::ColumnMap(const CsvReader& reader, std::initializer_list<const char*> known,
                     const std::vector<std::string>& canonical_names)
    : reader_(reader),
      known_(known.begin(), known.end()),
      index_(known.size(), reader.header().size()) {
  const std::vector<std::string>& header = reader.header();
  const std::string where = reader.name() + ":" + std::to_string(reader.header_line()) + ": ";
  std::set<std::string> other_names;
  for (size_t column = 0; column < header.size(); ++column) {
    const std::string& canonical = canonical_names[column];
    const auto it = std::find(known_.begin(), known_.end(), canonical);
    if (it == known_.end()) {
      if (!header[column].empty() && !other_names.insert(header[column]).second) {
        throw CsvError(where + "duplicate column " + Quoted(header[column]));
      }
      continue;
    }
    size_t& index = index_[it - known_.begin()];
    if (index != header.size()) {
      throw CsvError(where + "columns " + Quoted(header[index]) + " and " + Quoted(header[column]) +
                     " both give " + Quoted(canonical));
    }
    index = column;
  }
}

std::optional<size_t> ColumnMap::Find(std::string_view canonical) const {
  const auto it = std::find(known_.begin(), known_.end(), canonical);
  if (it == known_.end() || index_[it - known_.begin()] == reader_.header().size()) {
    return std::nullopt;
  }
  return index_[it - known_.begin()];
}

size_t ColumnMap::Require(std::string_view canonical) const {
  if (const std::optional<size_t> column = Find(canonical)) return *column;
  std::string names;
  for (const std::string& name : reader_.header()) names += (names.empty() ? "" : ",") + name;
  throw CsvError(reader_.name() + ":" + std::to_string(reader_.header_line()) +
                 ": missing required column " + Quoted(canonical) + " (columns: " + names + ")");
}

std::vector<size_t> ColumnMap::OtherNamedColumns() const {
  std::vector<size_t> columns;
  for (size_t column = 0; column < reader_.header().size(); ++column) {
    if (reader_.header()[column].empty()) continue;
    if (std::find(index_.begin(), index_.end(), column) == index_.end()) columns.push_back(column);
  }
  return columns;
}

bool IsMissing(const CsvField& field) {
  return field.text.empty() || EqualsIgnoreCase(field.text, "NA") ||
         EqualsIgnoreCase(field.text, "NaN");
}

double RequiredNumber(const CsvReader& reader, size_t column) {
  const CsvField& field = reader.fields()[column];
  if (field.text.empty()) reader.FailAt(column, "missing value (required)");
  if (IsMissing(field)) reader.FailAt(column, Quoted(field.text) + " is not allowed (required)");
  return ParseFinite(reader, column);
}

std::optional<double> OptionalNumber(const CsvReader& reader, size_t column) {
  if (IsMissing(reader.fields()[column])) return std::nullopt;
  return ParseFinite(reader, column);
}

std::optional<double> OptionalDiameter(const CsvReader& reader, size_t column) {
  const std::optional<double> value = OptionalNumber(reader, column);
  if (value && *value < 0) {
    reader.FailAt(column, Quoted(reader.fields()[column].text) + " is negative");
  }
  return value;
}

int64_t RequiredInteger(const CsvReader& reader, size_t column) {
  const CsvField& field = reader.fields()[column];
  if (field.text.empty()) reader.FailAt(column, "missing value (required)");
  return ParseInteger(reader, column);
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

}  // namespace forestmap::client
