#pragma once
// Tree lists as CSV files: surveyed maps (for upload and export), per-scan detections (for
// relocalization queries), per-frame detection sequences and their ground-truth poses.
//
// Columns are found by name, case-insensitively, ignoring surrounding spaces:
//   x | x_m, y | y_m            required, metres
//   z | z_m                     optional, metres (stem base height)
//   dbh | dbh_m                 optional, metres (stem diameter at breast height)
//   id | tree_id                optional, maps only; unique within the file: integers (also
//                               written 12.0) are the trees' ids; when any id is text (A1, 12a),
//                               the column is kept as a text attribute under its name, the rows
//                               carry it in text_id, and the trees get numeric ids when stored
//   score, axis_x, axis_y, axis_z, frame   detections only
// An empty field, NA or NaN in an optional numeric column means "unknown"; in x or y it is an
// error, as is an infinite value anywhere. In map files every other column is kept as a string
// attribute (species, height_m, ...); an unquoted empty field or NA there is an unknown value (a
// null attribute: the column stays, as a null field of an export, even when no row has a value),
// while a quoted "" or "NA" is the literal string (R's write.csv convention). Columns with an empty
// name (R's row names) are ignored. A header without data rows gives an empty list: whether that
// is acceptable is the caller's decision.
//
// Every error is a CsvError whose message is "FILE:LINE: column 'NAME': problem".

#include <cstdint>
#include <map>
#include <optional>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"
#include "client/io/csv_reader.h"
#include "client/io/tree_columns.h"

namespace forestmap::client {

// One tree of a map file, in the map frame.
struct MapTreeRow {
  std::optional<int64_t> id;           // nullopt: the server assigns one
  std::optional<std::string> text_id;  // an id that is no integer (A1), also kept as an attribute
  double x = 0;                        // m
  double y = 0;                        // m
  std::optional<double> z;             // m
  std::optional<double> dbh;           // m
  std::map<std::string, std::string> attributes;  // other columns, by header name
  std::set<std::string> null_attributes;          // other columns unknown (NA) in this row

  bool operator==(const MapTreeRow&) const = default;
};

// Readable one-line form, for messages and test failures.
std::ostream& operator<<(std::ostream& out, const MapTreeRow& row);

// One detected tree of a query file, in the sensor frame. An unknown z is 0 (the tree is taken
// to stand at sensor height); unknown dbh and score are NaN; an unknown axis is zero.
struct DetectedTreeRow {
  std::optional<int64_t> frame;  // the `frame` column, when the file has one
  algorithms::DetectedTree tree;
};

// The trees detected in one frame of a sequence.
struct Frame {
  int64_t frame = 0;
  std::vector<algorithms::DetectedTree> trees;
};

// `options` name columns and the DBH unit (io/tree_columns.h); DBH is returned in metres. A DBH
// column whose median is over 3 m is refused, naming the column.
// `header` set: receives the file's column names, in order.
std::vector<MapTreeRow> ReadMapTreesCsv(const std::string& path,
                                        const TreeFileOptions& options = {},
                                        std::vector<std::string>* header = nullptr);

// A tree table without a header row: 3DFin's `*_dbh_and_heights.txt` (blank-separated TH DBH
// X Y, DBH in m) as CSV text with the header TH,DBH,X,Y (TH stays an attribute); any other
// file whose first line is only numbers is refused (CsvError naming `path`); files with a
// header are returned unchanged. ReadMapTreesCsv and ParseMapTreesCsv apply it.
std::string HeaderlessTreeTable(std::string content, const std::string& path);

// Map rows as the relocalizer's trees: unknown z / dbh become NaN; a row without an id gets its
// index.
std::vector<algorithms::MapTree> ToMapTrees(const std::vector<MapTreeRow>& rows);
// As above for text in memory; `name` stands for the file name in messages.
std::vector<MapTreeRow> ParseMapTreesCsv(std::string content, const std::string& name,
                                         const TreeFileOptions& options = {},
                                         std::vector<std::string>* header = nullptr);

// Writes `id,x,y,z,dbh,<attributes>` with every number in its shortest form that
// reads back exactly, and empty fields for unknown values (null attributes, and attributes other
// rows have), so that reading the output gives the same rows (a column a row lacks reads back as
// a null attribute of that row); an attribute named like a tree column is written as attr_NAME
// (ExportedAttributes, tree_columns.h), and of two attributes one column would take (Species,
// species) the later one as attr_NAME. Throws CsvError (path form) when the file cannot be
// written.
// `order`: the attribute columns' order (ExportedAttributes).
void WriteMapTreesCsv(std::ostream& out, const std::vector<MapTreeRow>& rows,
                      const std::vector<std::string>& order = {});
void WriteMapTreesCsv(const std::string& path, const std::vector<MapTreeRow>& rows,
                      const std::vector<std::string>& order = {});

// All detections of a file, in file order.
std::vector<DetectedTreeRow> ReadDetectedTreesCsv(const std::string& path);
std::vector<DetectedTreeRow> ParseDetectedTreesCsv(std::string content, const std::string& name);

// Detections grouped by the (required) `frame` column, frames in order of first appearance.
std::vector<Frame> ReadFramesCsv(const std::string& path);
std::vector<Frame> ParseFramesCsv(std::string content, const std::string& name);

// `frame,timestamp,x,y,z,qx,qy,qz,qw` (timestamp optional): world_from_sensor of each frame.
// The quaternion (Hamilton, w scalar) must have unit norm to within 1%; it is normalised.
std::map<int64_t, algorithms::Pose3> ReadPosesCsv(const std::string& path);
std::map<int64_t, algorithms::Pose3> ParsePosesCsv(std::string content, const std::string& name);

// Odometry from a poses file (ReadPosesCsv) in any world frame: Next(frame), called for the
// frames in order, is the motion previous_sensor_from_sensor since the previous call's frame, or
// nullopt for the first frame and when either frame has no pose. An empty path: no odometry.
class OdometryFromPoses {
 public:
  explicit OdometryFromPoses(const std::string& poses_path)
      : poses_(poses_path.empty() ? std::map<int64_t, algorithms::Pose3>{}
                                  : ReadPosesCsv(poses_path)) {}
  std::optional<algorithms::Pose3> Next(int64_t frame);

 private:
  std::map<int64_t, algorithms::Pose3> poses_;
  const algorithms::Pose3* previous_ = nullptr;
};

}  // namespace forestmap::client
