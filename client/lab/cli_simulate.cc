// forestmap-lab simulate: simulated LiDAR scans of a forest, with exact truth, for testing trunk
// detection and relocalization end to end (algorithms/simulation/scan_simulation.h).
//
// Output folder:
//   map.csv              the scene's trees in the map frame (id,x,y,z,dbh; z = ground under the
//                        stem, dbh drawn where the input had none), readable by `forestmap map`
//   poses.csv            frame,timestamp,x,y,z,qx,qy,qz,qw: map_from_sensor of every scan
//   scan_NNN.pcd         the organised cloud (sensor frame; planar scanners: scan_NNN.csv with
//                        angle_rad,range_m)
//   scan_NNN_truth.csv   trees within the scanner's max range, sensor frame:
//                        tree_id,x,y,z,dbh,axis_x,axis_y,axis_z,range,stem_points,breast_points,
//                        visible (planar: tree_id,x,y,diameter,height,range,points,visible)
//   scan_NNN_labels.txt  with --labels: one label per point (tree index or negative class)

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <memory>
#include <random>
#include <sstream>
#include <thread>

#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/scan_simulation.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/scan_io.h"
#include "client/io/tree_csv.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

constexpr double kDeg = M_PI / 180.0;

struct SimulateOptions {
  std::string map_path;
  int generate = 0;
  std::string pose;  // x,y,height[,yaw[,pitch,roll]]
  int random_poses = 0;
  double min_height = 2, max_height = 15;  // m above ground, random poses
  double max_tilt_deg = 10;                // random poses
  std::string scanner = "os1-64";
  std::string out_dir;
  unsigned seed = 1;
  bool no_shrubs = false, no_crowns = false, no_branches = false, no_body = false;
  bool no_noise = false, no_divergence = false, mixed_pixels = false, labels = false;
  bool ascii = false;
  double dropout = 0;
  double slope = 0.1, undulation = 0.4;
  int threads = 0;  // 0 = all cores
};

std::vector<algorithms::MapTree> LoadForest(const SimulateOptions& o, std::string* source) {
  if (!o.map_path.empty()) {
    *source = o.map_path;
    std::vector<algorithms::MapTree> trees = ToMapTrees(ReadMapTreesCsv(o.map_path));
    if (trees.empty()) throw CommandError(o.map_path + ": the stem map has no trees");
    return trees;
  }
  algorithms::StemMapStatistics stats;  // ~500 trees/ha, DBH log-normal around 20 cm
  algorithms::ForestOptions forest;
  forest.width = forest.height = std::sqrt(o.generate / stats.density);
  forest.seed = o.seed;
  std::ostringstream text;
  text << "generated forest " << std::setprecision(4) << forest.width << " m x " << forest.width
       << " m";
  *source = text.str();
  return algorithms::GenerateForest(stats, forest);
}

// "x,y,height[,yaw[,pitch,roll]]" (m, m, m above ground, deg).
std::vector<double> ParsePose(const std::string& text) {
  std::vector<double> values;
  std::stringstream in(text);
  std::string field;
  while (std::getline(in, field, ',')) {
    size_t used = 0;
    double v = 0;
    try {
      v = std::stod(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != field.size() || !std::isfinite(v)) {
      throw CommandError("--pose: '" + field +
                         "' is not a number (expected x,y,z[,yaw[,pitch,roll]])");
    }
    values.push_back(v);
  }
  if (values.size() != 3 && values.size() != 4 && values.size() != 6) {
    throw CommandError("--pose: expected 3, 4 or 6 numbers x,y,z[,yaw[,pitch,roll]], got " +
                       std::to_string(values.size()));
  }
  values.resize(6, 0.0);
  return values;
}

std::vector<algorithms::Pose3> ChoosePoses(const SimulateOptions& o,
                                           const algorithms::ForestScene& scene,
                                           const std::vector<algorithms::MapTree>& trees) {
  std::vector<algorithms::Pose3> poses;
  if (!o.pose.empty()) {
    const std::vector<double> v = ParsePose(o.pose);
    const Eigen::Vector2d lo = scene.min_corner(), hi = scene.max_corner();
    if (v[0] < lo.x() || v[0] > hi.x() || v[1] < lo.y() || v[1] > hi.y()) {
      std::ostringstream message;
      message << "--pose: x,y = " << v[0] << "," << v[1] << " lies outside the scene [" << lo.x()
              << ", " << hi.x() << "] x [" << lo.y() << ", " << hi.y() << "] m";
      throw CommandError(message.str());
    }
    poses.push_back(
        algorithms::DronePose(scene, v[0], v[1], v[2], v[3] * kDeg, v[4] * kDeg, v[5] * kDeg));
    return poses;
  }
  const auto xy_yaw = algorithms::SamplePoses(trees, o.random_poses, 5.0, o.seed, 3, 20.0);
  if (xy_yaw.empty()) throw CommandError("no place in the map with 3 trees within 20 m");
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> height(o.min_height, o.max_height);
  std::uniform_real_distribution<double> tilt(-o.max_tilt_deg * kDeg, o.max_tilt_deg * kDeg);
  for (const Eigen::Vector3d& p : xy_yaw) {
    const double h = height(rng), pitch = tilt(rng), roll = tilt(rng);
    poses.push_back(algorithms::DronePose(scene, p.x(), p.y(), h, p.z(), pitch, roll));
  }
  return poses;
}

std::ofstream OpenOut(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw CommandError("cannot write " + path);
  out << std::setprecision(9);
  return out;
}

void WriteTruth(const std::string& path, const algorithms::ScanSimulationResult& scan,
                double max_range) {
  std::ofstream out = OpenOut(path);
  out << "tree_id,x,y,z,dbh,axis_x,axis_y,axis_z,range,stem_points,breast_points,visible\n";
  for (const algorithms::SimulatedTreeTruth& t : scan.trees) {
    if (t.range > max_range) continue;
    out << t.id << ',' << t.position.x() << ',' << t.position.y() << ',' << t.position.z() << ','
        << t.dbh << ',' << t.axis.x() << ',' << t.axis.y() << ',' << t.axis.z() << ',' << t.range
        << ',' << t.stem_points << ',' << t.breast_points << ',' << (t.visible ? 1 : 0) << '\n';
  }
  if (!out) throw CommandError("cannot write " + path);
}

void WritePlanarTruth(const std::string& path, const algorithms::PlanarScanSimulationResult& scan,
                      double max_range) {
  std::ofstream out = OpenOut(path);
  out << "tree_id,x,y,diameter,height,range,points,visible\n";
  for (const algorithms::PlanarTreeTruth& t : scan.trees) {
    if (t.range > max_range) continue;
    out << t.id << ',' << t.center.x() << ',' << t.center.y() << ',' << t.diameter << ','
        << t.height << ',' << t.range << ',' << t.points << ',' << (t.visible ? 1 : 0) << '\n';
  }
  if (!out) throw CommandError("cannot write " + path);
}

void WriteLabels(const std::string& path, const std::vector<int32_t>& labels) {
  std::ofstream out = OpenOut(path);
  for (int32_t label : labels) out << label << '\n';
  if (!out) throw CommandError("cannot write " + path);
}

void WriteSceneMap(const std::string& path, const algorithms::ForestScene& scene) {
  std::vector<MapTreeRow> rows;
  for (const algorithms::SceneTree& t : scene.trees()) {
    MapTreeRow row;
    row.id = t.id;
    row.x = t.base.x();
    row.y = t.base.y();
    row.z = t.base.z();
    row.dbh = t.dbh;
    rows.push_back(row);
  }
  WriteMapTreesCsv(path, rows);
}

std::string ScanName(const std::string& dir, size_t k) {
  char name[32];
  std::snprintf(name, sizeof(name), "/scan_%03zu", k);
  return dir + name;
}

algorithms::SceneOptions SceneOptionsFrom(const SimulateOptions& o) {
  algorithms::SceneOptions scene;
  scene.seed = o.seed;
  scene.shrubs = !o.no_shrubs;
  scene.crowns = !o.no_crowns;
  scene.branches = !o.no_branches;
  scene.max_slope = o.slope;
  scene.undulation = o.undulation;
  return scene;
}

struct ScanSummary {
  std::string written;  // the scan's file
  int returns = 0;
  int visible = 0;  // visible trees
};

// Simulates one scan and writes it with its truth (and labels) as `base`.*.
ScanSummary SimulateAndWrite(const algorithms::ForestScene& scene, const algorithms::Pose3& pose,
                             const algorithms::ScannerModel& scanner,
                             const algorithms::ScanNoiseOptions& noise, uint32_t seed,
                             const std::string& base, const SimulateOptions& o) {
  ScanSummary summary;
  if (scanner.IsPlanar()) {
    const auto scan = algorithms::SimulatePlanarScan(scene, pose, scanner, noise, seed);
    summary.written = base + ".csv";
    WritePlanarScan(summary.written, scan.scan);
    WritePlanarTruth(base + "_truth.csv", scan, scanner.max_range);
    if (o.labels) WriteLabels(base + "_labels.txt", scan.labels);
    for (const auto& tree : scan.trees) summary.visible += tree.visible;
    for (float r : scan.scan.ranges) summary.returns += std::isfinite(r);
    return summary;
  }
  const auto scan = algorithms::SimulateScan(scene, pose, scanner, noise, seed);
  summary.written = base + ".pcd";
  ScanWriteOptions write;
  write.pcd_encoding = o.ascii ? PcdEncoding::kAscii : PcdEncoding::kBinary;
  WriteScan(summary.written, scan.cloud, write);
  WriteTruth(base + "_truth.csv", scan, scanner.max_range);
  if (o.labels) WriteLabels(base + "_labels.txt", scan.labels);
  for (const auto& tree : scan.trees) summary.visible += tree.visible;
  summary.returns = scan.returns;
  return summary;
}

void Run(const SimulateOptions& o, CliContext& context) {
  if (o.map_path.empty() == (o.generate == 0)) {
    throw CommandError("give exactly one of --map STEMMAP.csv and --generate N");
  }
  if (o.pose.empty() == (o.random_poses == 0)) {
    throw CommandError("give exactly one of --pose x,y,z[,yaw[,pitch,roll]] and --random-poses K");
  }
  if (o.min_height > o.max_height) throw CommandError("--min-height must be <= --max-height");
  const algorithms::ScannerModel scanner = algorithms::ScannerPreset(o.scanner);
  algorithms::ScanNoiseOptions noise;
  noise.range_noise = !o.no_noise;
  noise.beam_divergence = !o.no_divergence;
  noise.mixed_pixels = o.mixed_pixels;
  noise.dropout = o.dropout;
  noise.drone_body = !o.no_body;
  noise.threads = o.threads > 0
                      ? o.threads
                      : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  noise.Check();

  std::string source;
  const std::vector<algorithms::MapTree> trees = LoadForest(o, &source);
  const algorithms::ForestScene scene(trees, SceneOptionsFrom(o));
  const std::vector<algorithms::Pose3> poses = ChoosePoses(o, scene, trees);
  std::filesystem::create_directories(o.out_dir);
  WriteSceneMap(o.out_dir + "/map.csv", scene);
  *context.err << "simulate: " << source << ": " << scene.trees().size() << " trees, "
               << scene.primitives().size() << " scene primitives -> " << o.out_dir << "/map.csv\n";

  std::ofstream pose_out = OpenOut(o.out_dir + "/poses.csv");
  pose_out << "frame,timestamp,x,y,z,qx,qy,qz,qw\n";
  for (size_t k = 0; k < poses.size(); ++k) {
    const algorithms::Pose3& pose = poses[k];
    const Eigen::Quaterniond q(pose.linear());
    const Eigen::Vector3d t = pose.translation();
    pose_out << k << ',' << k << ',' << t.x() << ',' << t.y() << ',' << t.z() << ',' << q.x() << ','
             << q.y() << ',' << q.z() << ',' << q.w() << '\n';
    const uint32_t seed = static_cast<uint32_t>(o.seed * 7919u + k);
    const std::string base = ScanName(o.out_dir, k);
    const auto start = std::chrono::steady_clock::now();
    const ScanSummary summary = SimulateAndWrite(scene, pose, scanner, noise, seed, base, o);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    *context.err << "simulate: scan " << k + 1 << "/" << poses.size() << " " << scanner.name
                 << " at " << std::fixed << std::setprecision(1) << t.x() << "," << t.y() << ","
                 << t.z() << ": " << summary.returns << " returns, " << summary.visible
                 << " visible trees -> " << summary.written << " (" << std::setprecision(2)
                 << seconds << " s)\n"
                 << std::defaultfloat << std::setprecision(6);
  }
  if (!pose_out) throw CommandError("cannot write " + o.out_dir + "/poses.csv");
}

// What the simulated scene and beams hold: vegetation, the drone's body, noise, terrain.
void AddSceneOptions(CLI::App* cmd, SimulateOptions& o) {
  cmd->add_flag("--no-shrubs", o.no_shrubs, "No shrubs");
  cmd->add_flag("--no-crowns", o.no_crowns, "No crowns");
  cmd->add_flag("--no-branches", o.no_branches, "No branches");
  cmd->add_flag("--no-body", o.no_body, "No returns from the drone's own body");
  cmd->add_flag("--no-noise", o.no_noise, "No range noise");
  cmd->add_flag("--no-divergence", o.no_divergence,
                "Thin beams: no footprint, no partial returns at stem edges");
  cmd->add_flag("--mixed-pixels", o.mixed_pixels,
                "Stem-edge beams that miss report a range between stem and background");
  cmd->add_option("--dropout", o.dropout, "Probability that a beam with a hit returns nothing")
      ->check(CLI::Range(0.0, 0.99))
      ->capture_default_str();
  cmd->add_option("--slope", o.slope, "Max terrain slope (m/m)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--undulation", o.undulation, "Terrain undulation amplitude (m)")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
}

}  // namespace

void AddSimulateCommand(CLI::App& app, CliContext& context) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Simulate LiDAR scans of a forest (stem map or generated) with exact truth: organised PCD "
      "scans, per-scan truth CSVs, the poses and the scene's tree map");
  auto* map = cmd->add_option("--map", o->map_path, "Stem map CSV (x,y[,dbh][,id]; m)")
                  ->check(CLI::ExistingFile);
  auto* generate = cmd->add_option("--generate", o->generate,
                                   "Generate a forest of about N trees (500 trees/ha)")
                       ->check(CLI::Range(1, 1000000));
  map->excludes(generate);
  auto* pose = cmd->add_option("--pose", o->pose,
                               "One scan from x,y,z[,yaw[,pitch,roll]]: x,y in the map frame (m), "
                               "z = height above the ground (m), angles in degrees");
  auto* random = cmd->add_option("--random-poses", o->random_poses,
                                 "K scans from random poses near trees (height and tilt below)")
                     ->check(CLI::Range(1, 100000));
  pose->excludes(random);
  cmd->add_option("--min-height", o->min_height, "Random poses: min height above ground (m)")
      ->check(CLI::Range(0.5, 200.0))
      ->capture_default_str();
  cmd->add_option("--max-height", o->max_height, "Random poses: max height above ground (m)")
      ->check(CLI::Range(0.5, 200.0))
      ->capture_default_str();
  cmd->add_option("--max-tilt", o->max_tilt_deg, "Random poses: max pitch and roll (deg)")
      ->check(CLI::Range(0.0, 80.0))
      ->capture_default_str();
  std::string names;
  for (const std::string& n : algorithms::ScannerPresetNames())
    names += (names.empty() ? "" : "|") + n;
  cmd->add_option("--scanner", o->scanner,
                  "Scanner preset: " + names + " (Ouster: -512|-1024 suffix for fewer columns)")
      ->capture_default_str();
  cmd->add_option("--out", o->out_dir, "Output folder")->required();
  cmd->add_option("--seed", o->seed, "Random seed (scene and scans)")->capture_default_str();
  AddSceneOptions(cmd, *o);
  cmd->add_flag("--labels", o->labels, "Also write scan_NNN_labels.txt (one label per point)");
  cmd->add_flag("--ascii", o->ascii, "Write ASCII PCD instead of binary");
  cmd->add_option("--threads", o->threads, "Worker threads (0 = all cores)")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  cmd->callback([o, &context] { context.run = [o, &context] { Run(*o, context); }; });
}

}  // namespace forestmap::client
