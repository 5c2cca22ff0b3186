#include "client/io/text_scan_io.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

using scan_io_internal::Fail;
using scan_io_internal::RawScan;

// Walks the lines of a text file, skipping blank lines and '#' comments (handed to a callback).
class LineCursor {
 public:
  LineCursor(const std::string& bytes, const std::string& path) : bytes_(bytes), path_(path) {
    if (bytes_.compare(0, 3, "\xEF\xBB\xBF") == 0) pos_ = 3;  // UTF-8 byte-order mark
  }

  // Next non-blank, non-comment line (trimmed); false at the end. Comments go to `on_comment`.
  template <typename OnComment>
  bool Next(std::string_view* line, OnComment&& on_comment) {
    while (pos_ < bytes_.size()) {
      size_t end = bytes_.find('\n', pos_);
      if (end == std::string::npos) end = bytes_.size();
      std::string_view text(bytes_.data() + pos_, end - pos_);
      pos_ = end + 1;
      ++line_number_;
      while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) {
        text.remove_suffix(1);
      }
      while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) {
        text.remove_prefix(1);
      }
      if (text.empty()) continue;
      if (text.front() == '#') {
        on_comment(text, Where());
        continue;
      }
      *line = text;
      return true;
    }
    return false;
  }

  std::string Where() const { return StrCat({path_, ":", std::to_string(line_number_)}); }

 private:
  const std::string& bytes_;
  const std::string& path_;
  size_t pos_ = 0;
  int line_number_ = 0;
};

// Splits on ',' (fields trimmed) when the line has one, else on runs of spaces and tabs.
void Split(std::string_view line, std::vector<std::string_view>* fields) {
  fields->clear();
  const bool commas = line.find(',') != std::string_view::npos;
  size_t at = 0;
  while (at <= line.size()) {
    if (!commas) {
      while (at < line.size() && (line[at] == ' ' || line[at] == '\t')) ++at;
      if (at >= line.size()) break;
    }
    size_t end = at;
    while (end < line.size() &&
           (commas ? line[end] != ',' : (line[end] != ' ' && line[end] != '\t'))) {
      ++end;
    }
    std::string_view field = line.substr(at, end - at);
    while (!field.empty() && (field.front() == ' ' || field.front() == '\t'))
      field.remove_prefix(1);
    while (!field.empty() && (field.back() == ' ' || field.back() == '\t')) field.remove_suffix(1);
    fields->push_back(field);
    at = end + 1;
  }
}

bool ParseNumber(std::string_view text, double* value) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  if (text.empty()) return false;
  const auto result = std::from_chars(text.data(), text.data() + text.size(), *value);
  return result.ec == std::errc() && result.ptr == text.data() + text.size();
}

std::string Normalise(std::string_view name) {
  while (!name.empty() && (name.front() == '/' || name.front() == '"')) name.remove_prefix(1);
  while (!name.empty() && name.back() == '"') name.remove_suffix(1);
  std::string out(name);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

bool IsHeader(const std::vector<std::string_view>& fields) {
  double unused = 0;
  for (std::string_view field : fields) {
    if (!ParseNumber(field, &unused)) return true;
  }
  return false;
}

// Column index of the first header name in `names`, or -1.
int FindColumn(const std::vector<std::string_view>& header,
               std::initializer_list<std::string_view> names) {
  for (size_t i = 0; i < header.size(); ++i) {
    const std::string name = Normalise(header[i]);
    for (std::string_view wanted : names) {
      if (name == wanted) return static_cast<int>(i);
    }
  }
  return -1;
}

// Parses the numbers of one data line into `values` (indexed by column).
// Takes the cursor, not its Where(): a message string per line would dominate the reading time.
void ParseRow(const std::vector<std::string_view>& fields, size_t expected,
              const LineCursor& cursor, std::vector<double>* values) {
  if (fields.size() != expected) {
    Fail(cursor.Where(), StrCat({"expected ", std::to_string(expected), " values, found ",
                                 std::to_string(fields.size())}));
  }
  values->resize(fields.size());
  for (size_t c = 0; c < fields.size(); ++c) {
    if (!ParseNumber(fields[c], &(*values)[c])) {
      Fail(cursor.Where(), StrCat({"column ", std::to_string(c + 1), ": '", std::string(fields[c]),
                                   "' is not a number"}));
    }
  }
}

void HandleScanComment(std::string_view comment, const std::string& where, RawScan* raw,
                       uint64_t* width, uint64_t* height) {
  scan_io_internal::ParseOffsetComment(comment, where, &raw->stated_offset);
  const size_t at = comment.find("organised:");
  if (at != std::string_view::npos) {
    std::istringstream dims{std::string(comment.substr(at + 10))};
    if (!(dims >> *width >> *height)) Fail(where, "'organised:' needs width and height");
  }
}

void AppendRow(std::string* out, std::initializer_list<float> values) {
  bool first = true;
  for (float v : values) {
    if (!first) *out += ',';
    first = false;
    scan_io_internal::AppendNumber(out, v);
  }
}

}  // namespace

RawScan ReadTextScan(const std::string& path) {
  const std::string bytes = scan_io_internal::ReadFileBytes(path);
  LineCursor cursor(bytes, path);
  RawScan raw;
  uint64_t width = 0, height = 0;
  auto on_comment = [&](std::string_view text, const std::string& where) {
    HandleScanComment(text, where, &raw, &width, &height);
  };
  std::string_view line;
  std::vector<std::string_view> fields;
  if (!cursor.Next(&line, on_comment)) Fail(path, "no points (only blank or comment lines)");
  Split(line, &fields);
  std::array<int, 5> column = {0, 1, 2, -1, -1};  // x y z intensity ring
  size_t expected = fields.size();
  bool have_row = true;
  if (IsHeader(fields)) {
    column = {FindColumn(fields, {"x"}), FindColumn(fields, {"y"}), FindColumn(fields, {"z"}),
              FindColumn(fields, {"intensity", "i", "scalar_intensity"}),
              FindColumn(fields, {"ring", "scalar_ring"})};
    if (column[0] < 0 || column[1] < 0 || column[2] < 0) {
      Fail(cursor.Where(), "header line has no x, y and z columns");
    }
    have_row = cursor.Next(&line, on_comment);
    if (have_row) Split(line, &fields);
  } else {
    if (expected < 3) {
      Fail(cursor.Where(),
           StrCat({"expected at least 3 values (x y z), found ", std::to_string(expected)}));
    }
    if (expected >= 4) column[3] = 3;
  }
  std::vector<double> values;
  for (; have_row; have_row = cursor.Next(&line, on_comment) && (Split(line, &fields), true)) {
    ParseRow(fields, expected, cursor, &values);
    for (int a = 0; a < 3; ++a) raw.xyz.push_back(values[column[a]]);
    if (column[3] >= 0) raw.intensity.push_back(static_cast<float>(values[column[3]]));
    if (column[4] >= 0) {
      const double r = values[column[4]];
      if (!(r >= 0 && r <= 65535)) Fail(cursor.Where(), "ring value out of range 0..65535");
      raw.ring.push_back(static_cast<uint16_t>(r));
    }
  }
  if (raw.size() > 0xFFFFFFFFull) Fail(path, "too many points");
  raw.width = static_cast<uint32_t>(raw.size());
  if (height > 1) {
    if (width * height != raw.size()) {
      Fail(path, StrCat({"point count mismatch: 'organised: ", std::to_string(width), " ",
                         std::to_string(height), "' but ", std::to_string(raw.size()), " points"}));
    }
    raw.width = static_cast<uint32_t>(width);
    raw.height = static_cast<uint32_t>(height);
  }
  return raw;
}

void WriteCsvScan(const std::string& path, const algorithms::PointCloud& cloud) {
  const bool has_intensity = !cloud.intensity.empty();
  const bool has_ring = !cloud.ring.empty();
  std::string out;
  out.reserve(cloud.size() * 40 + 128);
  if (!cloud.origin.isZero()) {
    out += StrCat({"# ForestMap scan; ", scan_io_internal::OffsetComment(cloud.origin), "\n"});
  }
  if (cloud.height > 1) {
    out += StrCat(
        {"# organised: ", std::to_string(cloud.width), " ", std::to_string(cloud.height), "\n"});
  }
  out += "x,y,z";
  if (has_intensity) out += ",intensity";
  if (has_ring) out += ",ring";
  out += '\n';
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    AppendRow(&out, {p.x(), p.y(), p.z()});
    if (has_intensity) AppendRow(&(out += ','), {cloud.intensity[i]});
    if (has_ring) out.append(",").append(std::to_string(cloud.ring[i]));
    out += '\n';
  }
  scan_io_internal::WriteFileBytes(path, out);
}

algorithms::PlanarScan ReadPlanarCsv(const std::string& path) {
  const std::string bytes = scan_io_internal::ReadFileBytes(path);
  LineCursor cursor(bytes, path);
  auto ignore_comment = [](std::string_view, const std::string&) {};
  std::string_view line;
  std::vector<std::string_view> fields;
  algorithms::PlanarScan scan;
  if (!cursor.Next(&line, ignore_comment)) Fail(path, "no beams (only blank or comment lines)");
  Split(line, &fields);
  int angle_column = 0, range_column = 1;
  const size_t expected = fields.size();
  bool have_row = true;
  if (IsHeader(fields)) {
    angle_column = FindColumn(fields, {"angle_rad", "angle"});
    range_column = FindColumn(fields, {"range_m", "range"});
    if (angle_column < 0 || range_column < 0) {
      Fail(cursor.Where(), "header line has no angle_rad and range_m columns");
    }
    have_row = cursor.Next(&line, ignore_comment);
    if (have_row) Split(line, &fields);
  } else if (expected < 2) {
    Fail(cursor.Where(), "expected 2 values (angle_rad,range_m), found 1");
  }
  std::vector<double> values;
  for (; have_row; have_row = cursor.Next(&line, ignore_comment) && (Split(line, &fields), true)) {
    ParseRow(fields, expected, cursor, &values);
    const double angle = values[angle_column];
    const double range = values[range_column];
    if (!std::isfinite(angle)) Fail(cursor.Where(), "angle_rad is not finite");
    if (range < 0) Fail(cursor.Where(), "range_m is negative");  // NaN and +inf mean "no return"
    scan.angles.push_back(static_cast<float>(angle));
    scan.ranges.push_back(static_cast<float>(range));
  }
  return scan;
}

void WritePlanarCsv(const std::string& path, const algorithms::PlanarScan& scan) {
  if (scan.angles.size() != scan.ranges.size()) {
    Fail(path, StrCat({"cannot write: ", std::to_string(scan.angles.size()), " angles but ",
                       std::to_string(scan.ranges.size()), " ranges"}));
  }
  std::string out = "angle_rad,range_m\n";
  out.reserve(out.size() + scan.size() * 24);
  for (size_t i = 0; i < scan.size(); ++i) {
    AppendRow(&out, {scan.angles[i], scan.ranges[i]});
    out += '\n';
  }
  scan_io_internal::WriteFileBytes(path, out);
}

}  // namespace forestmap::client
