// 3DFin's own tree table (declared in tree_csv.h): `<cloud>_dbh_and_heights.txt`, no header,
// one tree a line, fields separated by blanks: total height (m), DBH (m), X, Y.

#include <cctype>
#include <charconv>
#include <filesystem>
#include <string_view>
#include <vector>

#include "client/io/csv_columns.h"
#include "client/io/str_cat.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {
namespace {

constexpr std::string_view k3dfinSuffix = "_dbh_and_heights.txt";
constexpr size_t k3dfinFields = 4;                       // TH DBH X Y
constexpr std::string_view k3dfinHeader = "TH,DBH,X,Y";  // TH stays an attribute

// The blank-separated fields of one line.
std::vector<std::string_view> Words(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

bool IsNumber(std::string_view text) {
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  return ec == std::errc() && end == text.data() + text.size();
}

// The first non-blank line.
std::string_view FirstLine(std::string_view content) {
  size_t start = 0;
  while (start < content.size()) {
    const size_t end = std::min(content.find('\n', start), content.size());
    const std::string_view line = content.substr(start, end - start);
    if (!Words(line).empty()) return line;
    start = end + 1;
  }
  return {};
}

}  // namespace

std::string HeaderlessTreeTable(std::string content, const std::string& path) {
  const std::string_view first = FirstLine(content);
  const std::vector<std::string_view> words = Words(first);
  if (words.empty() || first.find_first_of(",;") != std::string_view::npos) return content;
  for (std::string_view word : words) {
    if (!IsNumber(word)) return content;  // a header (or text): read as it is
  }
  const std::string name = std::filesystem::path(path).filename().string();
  if (!name.ends_with(k3dfinSuffix) || words.size() != k3dfinFields) {
    throw CsvError(StrCat({path,
                           ": no header row (the first line is numbers): a tree table "
                           "needs one naming its columns (x,y,dbh,...); 3DFin's "
                           "*_dbh_and_heights.txt (TH DBH X Y) is read by that name"}));
  }
  std::string csv(k3dfinHeader);
  csv.push_back('\n');
  size_t start = 0;
  while (start < content.size()) {
    const size_t end = std::min(content.find('\n', start), content.size());
    const std::vector<std::string_view> fields =
        Words(std::string_view(content).substr(start, end - start));
    for (size_t i = 0; i < fields.size(); ++i) {
      if (i > 0) csv.push_back(',');
      csv.append(fields[i]);
    }
    if (!fields.empty()) csv.push_back('\n');
    start = end + 1;
  }
  return csv;
}

}  // namespace forestmap::client
