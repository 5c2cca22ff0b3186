// Writing map trees as CSV (declared in tree_csv.h).

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <utility>

#include "client/io/csv_columns.h"
#include "client/io/tree_columns.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {
namespace {

// Shortest text that reads back as exactly the same double.
void AppendNumber(std::string& out, double value) {
  char buffer[64];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, end);
}

// Quotes a field when reading it unquoted would change it: separators, quotes, line breaks,
// surrounding blanks (trimmed on read), and the empty string and NA (read as "absent").
void AppendText(std::string& out, std::string_view text) {
  const bool needs_quotes = text.empty() || text == "NA" ||
                            text.find_first_of(",\"\r\n") != std::string_view::npos ||
                            std::isspace(static_cast<unsigned char>(text.front())) ||
                            std::isspace(static_cast<unsigned char>(text.back()));
  if (!needs_quotes) {
    out.append(text);
    return;
  }
  out.push_back('"');
  for (char c : text) {
    if (c == '"') out.push_back('"');
    out.push_back(c);
  }
  out.push_back('"');
}

std::string Describe(const MapTreeRow& row, size_t index) {
  return "tree #" + std::to_string(index + 1) +
         (row.id ? " (id " + std::to_string(*row.id) + ")" : std::string());
}

void AppendRow(std::string& out, const MapTreeRow& row, size_t index,
               const std::vector<ExportedAttribute>& attribute_columns) {
  auto check = [&](double value, const char* what) {
    if (!std::isfinite(value)) {
      throw CsvError("cannot write " + Describe(row, index) + ": " + what + " is not finite");
    }
  };
  check(row.x, "x");
  check(row.y, "y");
  if (row.z) check(*row.z, "z");
  if (row.dbh) check(*row.dbh, "dbh");
  if (row.id) out.append(std::to_string(*row.id));
  out.push_back(',');
  AppendNumber(out, row.x);
  out.push_back(',');
  AppendNumber(out, row.y);
  out.push_back(',');
  if (row.z) AppendNumber(out, *row.z);
  out.push_back(',');
  if (row.dbh) AppendNumber(out, *row.dbh);
  for (const ExportedAttribute& attribute : attribute_columns) {
    out.push_back(',');
    const auto it = row.attributes.find(attribute.name);
    if (it != row.attributes.end()) AppendText(out, it->second);
  }
  out.push_back('\n');
}

}  // namespace

std::ostream& operator<<(std::ostream& out, const MapTreeRow& row) {
  std::string text = "{id ";
  text += row.id ? std::to_string(*row.id) : "-";
  text += ", x ";
  AppendNumber(text, row.x);
  text += ", y ";
  AppendNumber(text, row.y);
  for (const auto& [name, value] : {std::pair{", z ", row.z}, std::pair{", dbh ", row.dbh}}) {
    text += name;
    if (value) {
      AppendNumber(text, *value);
    } else {
      text += "-";
    }
  }
  for (const auto& [name, value] : row.attributes) {
    text += ", ";
    AppendText(text, name);
    text += " ";
    AppendText(text, value);
  }
  for (const std::string& name : row.null_attributes) {
    text += ", ";
    AppendText(text, name);
    text += " null";
  }
  return out << text << "}";
}

void WriteMapTreesCsv(std::ostream& out, const std::vector<MapTreeRow>& rows,
                      const std::vector<std::string>& order) {
  const std::vector<ExportedAttribute> attribute_columns = ExportedAttributes(rows, {}, order);
  std::string text = "id,x,y,z,dbh";
  for (const ExportedAttribute& attribute : attribute_columns) {
    text.push_back(',');
    AppendText(text, attribute.column);
  }
  text.push_back('\n');
  // Write in blocks so that a million-tree export does not hold its whole text twice.
  constexpr size_t kBlockBytes = 1 << 20;
  for (size_t i = 0; i < rows.size(); ++i) {
    AppendRow(text, rows[i], i, attribute_columns);
    if (text.size() >= kBlockBytes) {
      out.write(text.data(), static_cast<std::streamsize>(text.size()));
      text.clear();
    }
  }
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
}

void WriteMapTreesCsv(const std::string& path, const std::vector<MapTreeRow>& rows,
                      const std::vector<std::string>& order) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw CsvError(path + ": cannot write: " + std::strerror(errno));
  WriteMapTreesCsv(out, rows, order);
  out.flush();
  if (!out) throw CsvError(path + ": write failed: " + std::strerror(errno));
}

}  // namespace forestmap::client
