#include "client/io/tree_csv.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <unordered_map>
#include <utility>

#include "client/io/csv_columns.h"
#include "client/io/str_cat.h"
#include "client/io/tree_columns.h"
#include "client/io/utf8.h"

namespace forestmap::client {
namespace {

std::string DuplicateMessage(const char* what, int64_t value, int first_line, int line) {
  return StrCat({"duplicate ", what, " ", std::to_string(value), " (lines ",
                 std::to_string(first_line), " and ", std::to_string(line), ")"});
}

// Where the columns of a map file are; resolved once, not per row.
struct MapColumns {
  explicit MapColumns(const ColumnMap& columns)
      : x(columns.Require("x")),
        y(columns.Require("y")),
        z(columns.Find("z")),
        dbh(columns.Find("dbh")),
        id(columns.Find("id")),
        attributes(columns.OtherNamedColumns()) {}
  size_t x, y;
  std::optional<size_t> z, dbh, id;
  std::optional<size_t> dbh_fallback;  // read where dbh is unknown (TreeLoc++)
  std::vector<size_t> attributes;
};

// Attributes travel as Protobuf strings, which must be UTF-8: a stray Latin-1 byte would make
// the server unable to decode the upload message holding it.
void CheckUtf8(const CsvReader& reader, size_t column, std::string_view text, const char* what) {
  if (const std::optional<size_t> bad = FirstInvalidUtf8(text)) {
    char byte[8];
    std::snprintf(byte, sizeof(byte), "0x%02x", static_cast<unsigned char>(text[*bad]));
    reader.FailAt(column, StrCat({what, " is not valid UTF-8 (byte ", byte, " at offset ",
                                  std::to_string(*bad), "); save the file as UTF-8"}));
  }
}

MapTreeRow ReadMapRow(const CsvReader& reader, const MapColumns& columns, double dbh_scale) {
  MapTreeRow row;
  row.x = RequiredNumber(reader, columns.x);
  row.y = RequiredNumber(reader, columns.y);
  if (columns.z) row.z = OptionalNumber(reader, *columns.z);
  if (columns.dbh) row.dbh = OptionalDiameter(reader, *columns.dbh);
  if (!row.dbh && columns.dbh_fallback) row.dbh = OptionalDiameter(reader, *columns.dbh_fallback);
  if (row.dbh) *row.dbh *= dbh_scale;
  for (size_t column : columns.attributes) {
    const CsvField& field = reader.fields()[column];
    CheckUtf8(reader, column, reader.header()[column], "the column name");
    if (!field.quoted && (field.text.empty() || field.text == "NA")) {
      row.null_attributes.insert(reader.header()[column]);
      continue;
    }
    CheckUtf8(reader, column, field.text, "the value");
    row.attributes.emplace(reader.header()[column], std::string(field.text));
  }
  return row;
}

// An id as a survey writes it: an integer, or one with a zero fraction ("12.0", as spreadsheets
// export whole numbers); nullopt for text ids (A1, 12a, 1.5).
std::optional<int64_t> IntegerId(std::string_view text) {
  text = Trim(text);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  const size_t point = text.find('.');
  if (point != std::string_view::npos &&
      text.find_first_not_of('0', point + 1) == std::string_view::npos) {
    text = text.substr(0, point);
  }
  int64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

// The id column's fields as read, one per row (nullopt: missing).
struct IdColumn {
  size_t column = 0;
  std::vector<std::optional<std::string>> texts;
  std::vector<int> lines;
};

// Integer ids when every id is one; else text ids, kept as the attribute of the id column's name
// (the trees then get numeric ids where they are stored) and in text_id. Duplicates are refused.
void SetIds(std::vector<MapTreeRow>& rows, const IdColumn& ids, const CsvReader& reader,
            const TreeFileOptions& options) {
  const std::string& header = reader.header()[ids.column];
  bool integers = true;
  for (const auto& text : ids.texts) integers = integers && (!text || IntegerId(*text));
  std::unordered_map<std::string, int> line_of_id;
  for (size_t i = 0; i < rows.size(); ++i) {
    if (!ids.texts[i]) {
      if (!integers) rows[i].null_attributes.insert(header);
      continue;
    }
    const std::string key = integers ? std::to_string(*IntegerId(*ids.texts[i])) : *ids.texts[i];
    const auto [it, inserted] = line_of_id.emplace(key, ids.lines[i]);
    if (!inserted) {
      throw CsvError(StrCat({reader.name(), ":", std::to_string(ids.lines[i]), ": column '", header,
                             "': duplicate tree id ", key, " (lines ", std::to_string(it->second),
                             " and ", std::to_string(ids.lines[i]), ")"}));
    }
    if (integers) {
      rows[i].id = IntegerId(*ids.texts[i]);
    } else {
      rows[i].text_id = *ids.texts[i];
      rows[i].attributes[header] = *ids.texts[i];
    }
  }
  if (!integers && options.notes) {
    const auto example = *std::find_if(ids.texts.begin(), ids.texts.end(),
                                       [](const auto& text) { return text.has_value(); });
    *options.notes << "forestmap: " << reader.name() << ": column '" << header
                   << "' holds ids that are not integers (e.g. '" << *example
                   << "'): kept as the attribute '" << header
                   << "' (a map gives the trees numeric ids)" << std::endl;
  }
}

std::vector<MapTreeRow> ReadMapTrees(CsvReader reader, const TreeFileOptions& options) {
  const ResolvedColumns resolved = ResolveMapColumns(
      reader.header(), options, reader.name() + ":" + std::to_string(reader.header_line()));
  MapColumns columns(ColumnMap(reader, {"id", "x", "y", "z", "dbh"}, resolved.canonical));
  columns.dbh_fallback = resolved.dbh_fallback;
  const double dbh_scale = MetresPer(resolved.dbh_unit);
  std::vector<MapTreeRow> rows;
  IdColumn ids;
  if (columns.id) ids.column = *columns.id;
  while (reader.Next()) {
    rows.push_back(ReadMapRow(reader, columns, dbh_scale));
    if (!columns.id) continue;
    const CsvField& field = reader.fields()[*columns.id];
    ids.texts.push_back(IsMissing(field) ? std::nullopt
                                         : std::optional<std::string>(std::string(field.text)));
    ids.lines.push_back(reader.line());
  }
  if (columns.id) SetIds(rows, ids, reader, options);
  if (columns.dbh) {
    CheckDbhMedian(rows, reader.name(), reader.header()[*columns.dbh], resolved.dbh_unit);
  }
  return rows;
}

struct DetectionColumns {
  DetectionColumns(const ColumnMap& columns, bool require_frame)
      : frame(require_frame ? columns.Require("frame") : columns.Find("frame")),
        x(columns.Require("x")),
        y(columns.Require("y")),
        z(columns.Find("z")),
        dbh(columns.Find("dbh")),
        score(columns.Find("score")) {
    // The stem axis: all three columns or none.
    if (columns.Find("axis_x") || columns.Find("axis_y") || columns.Find("axis_z")) {
      axis = {columns.Require("axis_x"), columns.Require("axis_y"), columns.Require("axis_z")};
    }
  }
  std::optional<size_t> frame;
  size_t x, y;
  std::optional<size_t> z, dbh, score;
  std::optional<std::array<size_t, 3>> axis;
};

// The stem axis of a detection: all three components or none.
Eigen::Vector3d ReadAxis(const CsvReader& reader, const std::array<size_t, 3>& columns) {
  Eigen::Vector3d axis;
  int known = 0;
  for (int i = 0; i < 3; ++i) {
    const std::optional<double> value = OptionalNumber(reader, columns[i]);
    axis[i] = value.value_or(0.0);
    known += value.has_value();
  }
  if (known == 0) return axis;
  if (known == 3) {
    // A stem axis is a direction: normalised here so that every consumer sees a unit vector.
    return axis.norm() > 1e-9 ? Eigen::Vector3d(axis.normalized()) : Eigen::Vector3d::Zero();
  }
  for (size_t column : columns) {
    if (IsMissing(reader.fields()[column])) {
      reader.FailAt(column, "missing while other axis components are given");
    }
  }
  return axis;
}

std::vector<DetectedTreeRow> ReadDetections(CsvReader reader, bool require_frame) {
  const DetectionColumns columns(
      ColumnMap(reader, {"frame", "x", "y", "z", "dbh", "score", "axis_x", "axis_y", "axis_z"}),
      require_frame);
  std::vector<DetectedTreeRow> rows;
  while (reader.Next()) {
    DetectedTreeRow& row = rows.emplace_back();
    if (columns.frame) row.frame = RequiredInteger(reader, *columns.frame);
    algorithms::DetectedTree& tree = row.tree;
    tree.position.x() = RequiredNumber(reader, columns.x);
    tree.position.y() = RequiredNumber(reader, columns.y);
    if (columns.z) tree.position.z() = OptionalNumber(reader, *columns.z).value_or(0.0);
    if (columns.dbh) {
      tree.dbh = OptionalDiameter(reader, *columns.dbh).value_or(algorithms::kUnknown);
    }
    if (columns.score) {
      tree.score = OptionalNumber(reader, *columns.score).value_or(algorithms::kUnknown);
    }
    if (columns.axis) tree.axis = ReadAxis(reader, *columns.axis);
  }
  return rows;
}

std::vector<Frame> GroupFrames(std::vector<DetectedTreeRow> rows) {
  std::vector<Frame> frames;
  std::unordered_map<int64_t, size_t> index_of_frame;
  for (DetectedTreeRow& row : rows) {
    const auto [it, inserted] = index_of_frame.emplace(*row.frame, frames.size());
    if (inserted) frames.push_back(Frame{*row.frame, {}});
    frames[it->second].trees.push_back(row.tree);
  }
  return frames;
}

std::map<int64_t, algorithms::Pose3> ReadPoses(CsvReader reader) {
  const ColumnMap columns(reader, {"frame", "timestamp", "x", "y", "z", "qx", "qy", "qz", "qw"});
  const size_t frame_column = columns.Require("frame");
  std::array<size_t, 3> t;
  std::array<size_t, 4> q;  // w, x, y, z
  for (int i = 0; i < 3; ++i) t[i] = columns.Require(std::array{"x", "y", "z"}[i]);
  for (int i = 0; i < 4; ++i) q[i] = columns.Require(std::array{"qw", "qx", "qy", "qz"}[i]);
  std::map<int64_t, algorithms::Pose3> poses;
  std::unordered_map<int64_t, int> line_of_frame;
  while (reader.Next()) {
    const int64_t frame = RequiredInteger(reader, frame_column);
    const auto [it, inserted] = line_of_frame.emplace(frame, reader.line());
    if (!inserted) {
      reader.FailAt(frame_column, DuplicateMessage("frame", frame, it->second, reader.line()));
    }
    const Eigen::Quaterniond rotation(RequiredNumber(reader, q[0]), RequiredNumber(reader, q[1]),
                                      RequiredNumber(reader, q[2]), RequiredNumber(reader, q[3]));
    if (std::abs(rotation.norm() - 1.0) > 0.01) {
      reader.FailAt(q[0], "quaternion norm " + std::to_string(rotation.norm()) + " is not 1");
    }
    algorithms::Pose3 world_from_sensor = algorithms::Pose3::Identity();
    world_from_sensor.linear() = rotation.normalized().toRotationMatrix();
    world_from_sensor.translation() = Eigen::Vector3d(
        RequiredNumber(reader, t[0]), RequiredNumber(reader, t[1]), RequiredNumber(reader, t[2]));
    poses.emplace(frame, world_from_sensor);
  }
  return poses;
}

}  // namespace

std::vector<MapTreeRow> ReadMapTreesCsv(const std::string& path, const TreeFileOptions& options,
                                        std::vector<std::string>* header) {
  return ParseMapTreesCsv(ReadCsvFile(path), path, options, header);
}

std::vector<MapTreeRow> ParseMapTreesCsv(std::string content, const std::string& name,
                                         const TreeFileOptions& options,
                                         std::vector<std::string>* header) {
  CsvReader reader(HeaderlessTreeTable(std::move(content), name), name);
  if (header) *header = reader.header();
  return ReadMapTrees(std::move(reader), options);
}

std::vector<DetectedTreeRow> ReadDetectedTreesCsv(const std::string& path) {
  return ReadDetections(CsvReader::Open(path), /*require_frame=*/false);
}

std::vector<DetectedTreeRow> ParseDetectedTreesCsv(std::string content, const std::string& name) {
  return ReadDetections(CsvReader(std::move(content), name), /*require_frame=*/false);
}

std::vector<Frame> ReadFramesCsv(const std::string& path) {
  return GroupFrames(ReadDetections(CsvReader::Open(path), /*require_frame=*/true));
}

std::vector<Frame> ParseFramesCsv(std::string content, const std::string& name) {
  return GroupFrames(ReadDetections(CsvReader(std::move(content), name), /*require_frame=*/true));
}

std::map<int64_t, algorithms::Pose3> ReadPosesCsv(const std::string& path) {
  return ReadPoses(CsvReader::Open(path));
}

std::map<int64_t, algorithms::Pose3> ParsePosesCsv(std::string content, const std::string& name) {
  return ReadPoses(CsvReader(std::move(content), name));
}

std::vector<algorithms::MapTree> ToMapTrees(const std::vector<MapTreeRow>& rows) {
  std::vector<algorithms::MapTree> trees;
  trees.reserve(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    const MapTreeRow& r = rows[i];
    trees.push_back({r.id.value_or(static_cast<int64_t>(i)),
                     {r.x, r.y, r.z.value_or(algorithms::kUnknown)},
                     r.dbh.value_or(algorithms::kUnknown)});
  }
  return trees;
}

std::optional<algorithms::Pose3> OdometryFromPoses::Next(int64_t frame) {
  const auto pose = poses_.find(frame);
  const algorithms::Pose3* current = pose == poses_.end() ? nullptr : &pose->second;
  std::optional<algorithms::Pose3> motion;
  if (previous_ && current) motion = previous_->inverse() * *current;
  previous_ = current;
  return motion;
}

}  // namespace forestmap::client
