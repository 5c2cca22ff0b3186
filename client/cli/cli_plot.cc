// `forestmap plot`: an SVG or PNG picture of a map (client/cli/map_plot.h), optionally with one
// relocalization answer or a tracked path drawn on it.

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "client/cli/cli_commands.h"
#include "client/cli/cli_tree_crs.h"
#include "client/cli/cli_tree_input.h"
#include "client/cli/map_plot.h"

namespace forestmap::client {
namespace {

struct PlotCommandOptions {
  std::string map;         // a map on the server
  std::string trees_file;  // or a tree file
  std::string columns, dbh_unit;
  std::string out;
  std::string answer_file;      // JSON lines of `relocalize` / `track`
  std::string query_file;       // the answer's query trees (sensor frame)
  double match_distance = 0.5;  // m, a query tree this near a map tree counts as matched
  std::vector<double> window;   // min_x,min_y,max_x,max_y
  PlotOptions plot;
};

// "EPSG:n (name)" or the CRS's name, short enough for the picture's corner; "" for none.
std::string CrsLabel(const std::string& crs) {
  constexpr size_t kMaxLabel = 60;  // characters
  if (crs.empty()) return crs;
  const std::string label = DescribedCrs(crs);
  return label.size() <= kMaxLabel ? label : label.substr(0, kMaxLabel - 3) + "...";
}

void LoadTrees(const PlotCommandOptions& o, const CliContext& context, PlotInput& input) {
  if (!o.trees_file.empty()) {
    TreeFile file = ReadTreeFile(o.trees_file, TreeFileOptionsFrom(o.columns, o.dbh_unit));
    // Drawn in metres: a file in degrees or feet is drawn in its UTM zone.
    const std::string crs = ReprojectTrees(file.rows, o.trees_file, file.crs,
                                           InMetres(file.crs) ? "" : "utm", *context.err);
    for (const MapTreeRow& row : file.rows) input.trees.push_back({row.x, row.y, row.dbh, false});
    input.title = o.trees_file + ": " + std::to_string(input.trees.size()) + " trees";
    input.crs = CrsLabel(crs);
    return;
  }
  ForestMapClient client = context.Connect();
  const v1::Map map = client.GetMap(o.map);
  const ExportedTrees exported = client.ExportTrees(o.map);
  for (size_t i = 0; i < exported.trees.size(); ++i) {
    const MapTreeRow& row = exported.trees[i];
    input.trees.push_back({row.x, row.y, row.dbh, !exported.states[i].confirmed});
  }
  input.title = "map '" + o.map + "': " + std::to_string(input.trees.size()) + " trees, version " +
                std::to_string(exported.map_version);
  input.crs = CrsLabel(map.crs());
}

// Localized answers in order: a path; the last one is the sensor drawn.
void LoadAnswers(const std::string& path, PlotInput& input, Eigen::Isometry3d& map_from_sensor) {
  std::ifstream in(path);
  if (!in) throw CommandError(path + ": cannot read the answers");
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const nlohmann::json answer = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (answer.is_discarded() || !answer.is_object()) {
      throw CommandError(path + ":" + std::to_string(number) +
                         ": not a JSON answer of 'forestmap relocalize' or 'track'");
    }
    if (answer.value("status", "") != "localized") continue;
    if (!answer.contains("x") || !answer.contains("y") || !answer.contains("yaw_deg")) {
      throw CommandError(path + ":" + std::to_string(number) + ": a localized answer without x, " +
                         "y or yaw_deg");
    }
    PlotPose pose{answer["x"].get<double>(), answer["y"].get<double>(),
                  answer["yaw_deg"].get<double>() * M_PI / 180.0};
    input.path.emplace_back(pose.x, pose.y);
    input.sensor = pose;
    // The full 3-D pose places a tilted sensor's query trees (yaw alone would not).
    map_from_sensor = Eigen::Isometry3d::Identity();
    map_from_sensor.translation() = Eigen::Vector3d(pose.x, pose.y, answer.value("z", 0.0));
    map_from_sensor.linear() = Eigen::Quaterniond(answer.value("qw", 1.0), answer.value("qx", 0.0),
                                                  answer.value("qy", 0.0), answer.value("qz", 0.0))
                                   .normalized()
                                   .toRotationMatrix();
  }
  if (input.path.size() == 1) input.path.clear();  // one answer: the sensor alone
}

void PlaceQuery(const PlotCommandOptions& o, const Eigen::Isometry3d& map_from_sensor,
                PlotInput& input) {
  if (!input.sensor) throw CommandError("--query needs a localized answer (--answer)");
  for (const DetectedTreeRow& row : ReadDetectedTreesCsv(o.query_file)) {
    const Eigen::Vector3d& q = row.tree.position;
    const Eigen::Vector2d p = (map_from_sensor * q).head<2>();
    input.sensor_range = std::max(input.sensor_range, q.head<2>().norm());
    bool matched = false;
    for (const PlotTree& tree : input.trees) {
      matched = matched || std::hypot(tree.x - p.x(), tree.y - p.y()) <= o.match_distance;
    }
    (matched ? input.matched : input.unmatched).push_back(p);
  }
}

void Run(PlotCommandOptions o, const CliContext& context) {
  if (o.map.empty() == o.trees_file.empty()) {
    throw CommandError("give a map NAME or --trees FILE (one of them)");
  }
  PlotInput input;
  LoadTrees(o, context, input);
  Eigen::Isometry3d map_from_sensor = Eigen::Isometry3d::Identity();
  if (!o.answer_file.empty()) LoadAnswers(o.answer_file, input, map_from_sensor);
  if (!o.query_file.empty()) PlaceQuery(o, map_from_sensor, input);
  if (!o.window.empty()) {
    if (o.window.size() != 4 || o.window[2] <= o.window[0] || o.window[3] <= o.window[1]) {
      throw CommandError("--window: give MIN_X,MIN_Y,MAX_X,MAX_Y with MIN < MAX");
    }
    o.plot.window = Eigen::Vector4d(o.window[0], o.window[1], o.window[2], o.window[3]);
  }
  try {
    WritePlot(o.out, input, o.plot);
  } catch (const std::runtime_error& e) {
    throw CommandError(e.what());
  }
  *context.err << "plot: " << input.trees.size() << " trees -> " << o.out << std::endl;
}

}  // namespace

void AddPlotCommand(CLI::App& app, CliContext& context) {
  auto o = std::make_shared<PlotCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "plot",
      "Draw a map as SVG or PNG: stems to scale, candidates vs confirmed, a grid with the "
      "map's coordinates, scale bar, north arrow, CRS, DBH key; optionally a relocalization "
      "answer or a tracked path");
  sub->add_option("NAME", o->map, "Map name (or --trees FILE)");
  sub->add_option("--trees", o->trees_file, "Draw a tree file instead of a map");
  AddTreeFileOptions(*sub, o->columns, o->dbh_unit);
  sub->add_option("--out", o->out, "The picture: FILE.svg or FILE.png")->required();
  sub->add_option("--answer", o->answer_file,
                  "JSON lines of 'forestmap relocalize' or 'track': the sensor (last localized "
                  "answer) and, for several, the path");
  sub->add_option("--query", o->query_file,
                  "The answer's query trees (CSV, sensor frame): matched ones in blue, "
                  "unmatched in red");
  sub->add_option("--size", o->plot.size_px, "Longer side of the map area, px (default 900)")
      ->check(CLI::Range(100, 10000));
  sub->add_option("--window", o->window, "Only MIN_X,MIN_Y,MAX_X,MAX_Y (m, map frame)")
      ->delimiter(',');
  sub->callback([o, &context] { context.run = [o, &context] { Run(*o, context); }; });
}

}  // namespace forestmap::client
