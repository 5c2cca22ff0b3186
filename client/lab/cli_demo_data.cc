// forestmap-lab demo-data: a forest map and one drone's view of it, with the true pose, for the
// README's end-to-end demo. Uses a real surveyed stem map when given one (e.g.
// ../shared/data/stemmaps/spatstat_longleaf.csv), else generates a forest.

#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>

#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

struct DemoOptions {
  std::string out_dir = "demo-out";
  std::string stemmap;  // optional real stem map
  double range = 20;    // m
  unsigned seed = 7;
};

std::vector<algorithms::MapTree> DemoForest(const DemoOptions& o, std::string* source) {
  if (!o.stemmap.empty() && std::filesystem::exists(o.stemmap)) {
    *source = "real stem map " + o.stemmap;
    return ToMapTrees(ReadMapTreesCsv(o.stemmap));
  }
  algorithms::StemMapStatistics stats;  // ~500 trees/ha, DBH log-normal around 20 cm
  algorithms::ForestOptions forest;
  forest.width = forest.height = 150;
  forest.z_amplitude = 3;
  forest.seed = o.seed;
  *source = "generated forest (150 m x 150 m, uneven terrain)";
  return algorithms::GenerateForest(stats, forest);
}

void WriteQuery(const std::string& path, const std::vector<algorithms::DetectedTree>& trees) {
  std::ofstream out(path);
  out << std::setprecision(9) << "x,y,z,dbh,axis_x,axis_y,axis_z,score\n";
  for (const auto& t : trees) {
    out << t.position.x() << ',' << t.position.y() << ',' << t.position.z() << ',';
    if (algorithms::IsKnown(t.dbh)) out << t.dbh;
    out << ',' << t.axis.x() << ',' << t.axis.y() << ',' << t.axis.z() << ',';
    if (algorithms::IsKnown(t.score)) out << t.score;
    out << '\n';
  }
  if (!out) throw CommandError("cannot write " + path);
}

void Run(const DemoOptions& o, CliContext& context) {
  std::filesystem::create_directories(o.out_dir);
  std::string source;
  const std::vector<algorithms::MapTree> forest = DemoForest(o, &source);
  algorithms::ViewSimulator simulator(forest);
  const auto poses = simulator.SamplePoses(1, o.range, o.seed, 15, o.range);
  if (poses.empty()) throw CommandError("no place in the map where a drone sees 15 trees");
  algorithms::ViewOptions view;  // occlusion, 30% misses, 20% false stems, 5 cm noise
  view.range = o.range;
  view.max_tilt = 0.25;  // rad: a drone is not level
  view.seed = o.seed;
  const algorithms::SimulatedView v = simulator.Simulate(poses[0].head<2>(), poses[0].z(), view);

  std::vector<MapTreeRow> rows;
  for (const auto& t : forest) {
    MapTreeRow row;
    row.id = t.id;
    row.x = t.position.x();
    row.y = t.position.y();
    if (algorithms::IsKnown(t.position.z())) row.z = t.position.z();
    if (algorithms::IsKnown(t.dbh)) row.dbh = t.dbh;
    rows.push_back(row);
  }
  WriteMapTreesCsv(o.out_dir + "/map.csv", rows);
  WriteQuery(o.out_dir + "/query.csv", v.trees);
  const Eigen::Quaterniond q(v.map_from_sensor.linear());
  const Eigen::Vector3d t = v.map_from_sensor.translation();
  const nlohmann::json truth = {
      {"x", t.x()},  {"y", t.y()},
      {"z", t.z()},  {"qx", q.x()},
      {"qy", q.y()}, {"qz", q.z()},
      {"qw", q.w()}, {"yaw_deg", algorithms::YawOf(v.map_from_sensor.linear()) * 180 / M_PI}};
  std::ofstream(o.out_dir + "/truth.json") << truth.dump() << "\n";
  int false_stems = 0;
  for (int64_t id : v.truth_ids) false_stems += id < 0;
  *context.err << "demo-data: " << source << ": " << forest.size() << " trees -> " << o.out_dir
               << "/map.csv\n"
               << "demo-data: drone view: " << v.trees.size() << " detected trees (" << false_stems
               << " false stems) within " << o.range << " m, tilted -> " << o.out_dir
               << "/query.csv; true pose -> " << o.out_dir << "/truth.json\n";
}

}  // namespace

void AddDemoDataCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<DemoOptions>();
  CLI::App* cmd = app.add_subcommand(
      "demo-data", "Write a demo forest map, one simulated drone view of it and its true pose");
  cmd->add_option("--out", options->out_dir, "Output folder")->capture_default_str();
  cmd->add_option("--stemmap", options->stemmap,
                  "Real stem map CSV to use when it exists (else a forest is generated)");
  cmd->add_option("--range", options->range, "Sensor range (m)")
      ->check(CLI::Range(5.0, 100.0))
      ->capture_default_str();
  cmd->add_option("--seed", options->seed, "Random seed")->capture_default_str();
  cmd->callback(
      [options, &context] { context.run = [options, &context] { Run(*options, context); }; });
}

}  // namespace forestmap::client
