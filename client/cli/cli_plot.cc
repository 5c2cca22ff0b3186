// `forestmap plot`: an SVG or PNG picture of a map (client/cli/map_plot.h), optionally with one
// relocalization answer or a tracked path drawn on it.

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
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
  std::string colour_by;        // an attribute column: stems coloured by its values
  PlotOptions plot;
};

// Labels on more stems than this are unreadable: a crowded picture gets none, and says why.
constexpr size_t kMaxLabels = 1'500;

// A tree of a file or a map as drawn: its id as label, the `colour_by` column as its category.
PlotTree PlotTreeOf(const MapTreeRow& row, bool candidate, const std::string& colour_by) {
  PlotTree tree{row.x, row.y, row.dbh, candidate};
  if (row.id) tree.label = std::to_string(*row.id);
  if (row.text_id) tree.label = *row.text_id;
  if (!colour_by.empty()) {
    const auto value = row.attributes.find(colour_by);
    if (value != row.attributes.end()) tree.category = value->second;
  }
  return tree;
}

// Refuses a --color-by column that no tree has, naming the columns there are.
void CheckColourColumn(const std::string& column, const std::vector<MapTreeRow>& rows) {
  if (column.empty()) return;
  std::set<std::string> columns;
  for (const MapTreeRow& row : rows) {
    for (const auto& [name, value] : row.attributes) columns.insert(name);
    columns.insert(row.null_attributes.begin(), row.null_attributes.end());
  }
  if (columns.count(column)) return;
  std::string known;
  for (const std::string& name : columns) known += (known.empty() ? "" : ", ") + name;
  throw CommandError("--color-by " + column + ": no tree has that column (" +
                     (known.empty() ? "the trees have no attributes" : "they have " + known) + ")");
}

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
    CheckColourColumn(o.colour_by, file.rows);
    for (const MapTreeRow& row : file.rows) {
      input.trees.push_back(PlotTreeOf(row, false, o.colour_by));
    }
    input.title = o.trees_file + ": " + std::to_string(input.trees.size()) + " trees";
    input.crs = CrsLabel(crs);
    return;
  }
  ForestMapClient client = context.Connect();
  const v1::Map map = client.GetMap(o.map);
  const ExportedTrees exported = client.ExportTrees(o.map);
  CheckColourColumn(o.colour_by, exported.trees);
  for (size_t i = 0; i < exported.trees.size(); ++i) {
    input.trees.push_back(
        PlotTreeOf(exported.trees[i], !exported.states[i].confirmed, o.colour_by));
  }
  input.title = "map '" + o.map + "': " + std::to_string(input.trees.size()) + " trees, version " +
                std::to_string(exported.map_version);
  input.boundary = exported.boundary;
  input.crs = CrsLabel(map.crs());
}

// Localized answers in order: a path; the last one is the sensor drawn.
// The last localized answer's inliers (query trees the server matched), when it states them.
void LoadAnswers(const std::string& path, PlotInput& input, Eigen::Isometry3d& map_from_sensor,
                 std::optional<int>& inliers) {
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
    inliers.reset();
    if (answer.contains("inliers") && answer["inliers"].is_number_integer()) {
      inliers = answer["inliers"].get<int>();
    }
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

// Places the query trees with the answer's pose, and warns when they do not lie on the map where
// the answer says: fewer matched than half the server's inliers (or, without them, than half the
// query) means the query is another frame's, or the answer another map's.
void PlaceQuery(const PlotCommandOptions& o, const Eigen::Isometry3d& map_from_sensor,
                std::optional<int> inliers, PlotInput& input, std::ostream& err) {
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
  const size_t matched = input.matched.size(), query = matched + input.unmatched.size();
  const size_t expected = inliers ? static_cast<size_t>(std::max(*inliers, 0)) : query;
  if (2 * matched < expected) {
    err << "plot: warning: " << matched << " of the " << query << " query trees lie on a map tree"
        << (inliers ? " where the answer matched " + std::to_string(*inliers) : std::string())
        << ": the answer and the query (or the map) do not belong together" << std::endl;
  }
}

void Run(PlotCommandOptions o, const CliContext& context) {
  if (o.map.empty() == o.trees_file.empty()) {
    throw CommandError("give a map NAME or --trees FILE (one of them)");
  }
  PlotInput input;
  LoadTrees(o, context, input);
  input.category_name = o.colour_by;
  Eigen::Isometry3d map_from_sensor = Eigen::Isometry3d::Identity();
  std::optional<int> inliers;
  if (!o.answer_file.empty()) LoadAnswers(o.answer_file, input, map_from_sensor, inliers);
  if (!o.query_file.empty()) PlaceQuery(o, map_from_sensor, inliers, input, *context.err);
  if (!o.window.empty()) {
    if (o.window.size() != 4 || o.window[2] <= o.window[0] || o.window[3] <= o.window[1]) {
      throw CommandError("--window: give MIN_X,MIN_Y,MAX_X,MAX_Y with MIN < MAX");
    }
    o.plot.window = Eigen::Vector4d(o.window[0], o.window[1], o.window[2], o.window[3]);
  }
  if (o.plot.labels) {
    const size_t shown = std::count_if(input.trees.begin(), input.trees.end(), [&](const auto& t) {
      return o.window.empty() ||
             (t.x >= o.window[0] && t.x <= o.window[2] && t.y >= o.window[1] && t.y <= o.window[3]);
    });
    if (shown > kMaxLabels) {
      o.plot.labels = false;
      *context.err << "plot: warning: no labels: " << shown << " trees in the picture (at most "
                   << kMaxLabels << " are labelled; draw a --window)" << std::endl;
    }
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
  sub->add_flag("--labels", o->plot.labels,
                "Each tree's id beside its stem (up to 1,500 trees in the picture)");
  sub->add_option("--color-by", o->colour_by,
                  "An attribute column (e.g. a species code): stems coloured by its value, the 8 "
                  "most frequent values each their own colour, the rest grey");
  sub->callback([o, &context] { context.run = [o, &context] { Run(*o, context); }; });
}

}  // namespace forestmap::client
