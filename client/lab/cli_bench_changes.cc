// forestmap-lab bench-changes: a stem map, its simulated future, drone passes over the future
// observed into the original map, in process, scored against the future's truth.
//
// The future: --felled of the trees felled at random, every tree in a disc of --clear-cut ha
// felled, --ingrowth new trees (per original tree) at random places >= 1.5 m from a standing
// trunk, DBH 5-12 cm, and every standing tree grown by --growth m of DBH. The passes: lawnmower
// lines --line-spacing m apart (alternately along x and along y, offset at random), a frame every
// --frame-step m, simulated views of the future forest (algorithms/simulation/view_simulator.h:
// occlusion, misses rising with range, --false-rate false stems per detection, position and DBH
// noise), each frame placed with its true pose plus a relocalized drone's error (--pose-sigma m
// per axis, --yaw-sigma deg), one source per pass. Each frame goes through MergedMap::Observe
// (algorithms/merging/merged_map.h): the evidence of absence, the merge, the removals.
// Prints the share of felled trees removed, of live trees wrongly removed, of new trees confirmed,
// candidates left per real tree, the DBH growth error, the time per frame, and how many views of
// the future forest relocalize right and wrong on the original and on the updated map (its
// confirmed trees, removed ones left out) (text or --json).
// --write DIR also writes each pass as `forestmap observe` reads it (pass<k>_trees.csv, detections
// in the sensor frame; pass<k>_poses.csv, every frame's pose, those that detected nothing too)
// and the truth (truth.json: felled ids, new trees, growth), for tests/bench/changes_server.sh.
// Same day:  --map MAP.csv --frames trees.csv --poses poses.csv [--truth-offset ...]
//   real frames of the mapped forest, cut into sources of --source-frames frames, observed into
//   the map: nothing changed, so every tree removed is wrong.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>

#include "algorithms/core/kdtree.h"
#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/merging/merged_map.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "client/lab/bench_changes_files.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

using algorithms::MapTree;

struct BenchChangesOptions {
  std::string map_path;
  double felled = 0.3;     // share of trees felled at random
  double clear_cut = 0.5;  // ha, a disc felled entirely
  double ingrowth = 0.1;   // new trees per original tree
  double growth = 0.01;    // m of DBH added to every standing tree
  int passes = 5;
  double false_rate = 0.1;   // false stems per detected tree
  double range = 15;         // m
  double line_spacing = 10;  // m
  double frame_step = 3;     // m
  double pose_sigma = 0.05;  // m per axis
  double yaw_sigma = 0.2;    // deg
  unsigned seed = 1;
  // Real frames of the same day (--frames, --poses): nothing changed, every removal is wrong.
  std::string frames_path, poses_path;
  std::vector<double> truth_offset;  // x, y, z (m), yaw (deg): map_from_world of --poses
  int source_frames = 100;           // frames per source (a drone's share of the traversal)
  int reloc_views = 200;             // views of the future relocalized on both maps (0: none)
  bool no_absence = false;           // merge only, as without the evidence of absence
  std::string write_dir;             // set: the passes and the truth are written there
  bool json = false;
};

struct Future {
  std::vector<MapTree> trees;  // standing originals (grown) and ingrowth (ids > max original)
  std::set<int64_t> felled;    // original ids
  std::vector<MapTree> ingrowth;
  Eigen::Vector2d clear_cut_center = Eigen::Vector2d::Zero();
  double clear_cut_radius = 0;  // m
};

Future MakeFuture(const std::vector<MapTree>& map, const BenchChangesOptions& o,
                  const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, std::mt19937& rng) {
  Future future;
  future.clear_cut_radius = std::sqrt(o.clear_cut * 1e4 / M_PI);
  const Eigen::Vector2d margin =
      (hi - lo).cwiseMin(Eigen::Vector2d::Constant(2 * future.clear_cut_radius)) / 2;
  std::uniform_real_distribution<double> ux(lo.x() + margin.x(), hi.x() - margin.x());
  std::uniform_real_distribution<double> uy(lo.y() + margin.y(), hi.y() - margin.y());
  future.clear_cut_center = {ux(rng), uy(rng)};
  std::vector<size_t> order(map.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  const size_t at_random = static_cast<size_t>(std::lround(o.felled * map.size()));
  for (size_t k = 0; k < at_random; ++k) future.felled.insert(map[order[k]].id);
  int64_t next_id = 1;
  for (const MapTree& tree : map) {
    next_id = std::max(next_id, tree.id + 1);
    if ((tree.position.head<2>() - future.clear_cut_center).norm() <= future.clear_cut_radius) {
      future.felled.insert(tree.id);
    }
  }
  for (const MapTree& tree : map) {
    if (future.felled.count(tree.id)) continue;
    MapTree grown = tree;
    if (algorithms::IsKnown(grown.dbh)) grown.dbh += o.growth;
    future.trees.push_back(grown);
  }
  std::uniform_real_distribution<double> px(lo.x(), hi.x()), py(lo.y(), hi.y()), dbh(0.05, 0.12);
  const int wanted = static_cast<int>(std::lround(o.ingrowth * map.size()));
  for (int tries = 0; static_cast<int>(future.ingrowth.size()) < wanted && tries < 1000 * wanted;
       ++tries) {
    const Eigen::Vector2d xy(px(rng), py(rng));
    bool clear = true;
    for (const MapTree& tree : future.trees) clear &= (tree.position.head<2>() - xy).norm() >= 1.5;
    if (!clear) continue;
    MapTree tree{next_id++, Eigen::Vector3d(xy.x(), xy.y(), 0), dbh(rng)};
    future.ingrowth.push_back(tree);
    future.trees.push_back(tree);
  }
  return future;
}

double Median(std::vector<double> values) {
  if (values.empty()) return algorithms::kUnknown;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

double Share(double part, double whole) { return whole > 0 ? part / whole : 0.0; }

// Views of the future forest relocalized without a prior on `map`: how many are right (within
// 0.5 m and 5 deg) and how many wrong (localized more than 1 m or 5 deg off).
nlohmann::ordered_json RelocOn(const std::vector<MapTree>& map, const Future& future, int views,
                               unsigned seed) {
  const algorithms::MapIndex index(map);
  const algorithms::ViewSimulator simulator(future.trees);
  const std::vector<Eigen::Vector3d> poses = simulator.SamplePoses(views, 0, seed, 8, 15);
  int correct = 0, wrong = 0;
  for (size_t k = 0; k < poses.size(); ++k) {
    algorithms::ViewOptions view;
    view.seed = seed + static_cast<unsigned>(k);
    const algorithms::SimulatedView sim =
        simulator.Simulate(poses[k].head<2>(), poses[k].z(), view);
    algorithms::RelocalizeQuery query;
    query.trees = sim.trees;
    const algorithms::RelocalizeResult result = algorithms::Relocalize(index, query);
    if (result.status != algorithms::RelocalizeStatus::kLocalized) continue;
    const algorithms::PoseError error =
        algorithms::ComparePoses(result.map_from_sensor, sim.map_from_sensor);
    correct += error.xy <= 0.5 && error.yaw <= 5;
    wrong += error.xy > 1 || error.yaw > 5;
  }
  nlohmann::ordered_json report;
  report["views"] = poses.size();
  report["correct"] = correct;
  report["wrong"] = wrong;
  return report;
}

nlohmann::ordered_json Score(const std::vector<MapTree>& map, const Future& future,
                             const algorithms::MergedMap& merged, const BenchChangesOptions& o,
                             int64_t frames, double seconds) {
  int64_t max_original = 0;
  for (const MapTree& tree : map) max_original = std::max(max_original, tree.id);
  int felled_removed = 0, live_removed = 0, candidates_retired = 0;
  for (const auto& [id, removed] : merged.removed()) {
    if (id > max_original) {
      ++candidates_retired;
    } else {
      (future.felled.count(id) ? felled_removed : live_removed)++;
    }
  }
  const std::vector<algorithms::TreeEstimate> trees = merged.Trees();
  int candidates = 0, confirmed = 0;
  std::vector<algorithms::KdTree<double, 2>::Point> new_xy;
  for (const auto& tree : trees) {
    if (tree.status == algorithms::TreeStatus::kCandidate) ++candidates;
    if (tree.status != algorithms::TreeStatus::kConfirmed) continue;
    ++confirmed;
    if (tree.id > max_original) new_xy.push_back({tree.position.x(), tree.position.y()});
  }
  int new_confirmed = 0;
  if (!new_xy.empty()) {
    const algorithms::KdTree<double, 2> index(std::move(new_xy));
    for (const MapTree& tree : future.ingrowth) {
      const auto nearest = index.Nearest({tree.position.x(), tree.position.y()});
      new_confirmed += nearest.first >= 0 && nearest.second <= 0.5 * 0.5;
    }
  }
  std::map<int64_t, double> original_dbh;
  for (const MapTree& tree : map) original_dbh[tree.id] = tree.dbh;
  std::vector<double> growth_error;
  for (const auto& tree : trees) {
    const auto it = original_dbh.find(tree.id);
    if (it == original_dbh.end() || future.felled.count(tree.id) ||
        !algorithms::IsKnown(it->second) || !algorithms::IsKnown(tree.dbh)) {
      continue;
    }
    growth_error.push_back(std::abs(tree.dbh - it->second - o.growth));
  }
  const double live = static_cast<double>(map.size() - future.felled.size());
  nlohmann::ordered_json report;
  report["trees"] = map.size();
  report["felled"] = future.felled.size();
  report["new_trees"] = future.ingrowth.size();
  report["frames"] = frames;
  report["felled_removed"] = Share(felled_removed, static_cast<double>(future.felled.size()));
  report["live_removed"] = Share(live_removed, live);
  report["live_removed_count"] = live_removed;
  report["new_confirmed"] = Share(new_confirmed, static_cast<double>(future.ingrowth.size()));
  report["candidates_left"] = candidates;
  report["candidates_per_real_tree"] = Share(candidates, static_cast<double>(future.trees.size()));
  report["candidates_retired"] = candidates_retired;
  report["confirmed_trees"] = confirmed;
  report["dbh_growth_median_error_mm"] = 1000 * Median(growth_error);
  report["ms_per_frame"] = frames > 0 ? 1000 * seconds / static_cast<double>(frames) : 0.0;
  if (o.reloc_views > 0) {
    report["reloc_original_map"] = RelocOn(map, future, o.reloc_views, o.seed);
    report["reloc_updated_map"] =
        RelocOn(merged.ConfirmedMapTrees(), future, o.reloc_views, o.seed);
  }
  return report;
}

// Real frames of the forest the map shows, the same day: every tree removed is wrong. The
// traversal is cut into sources of `source_frames` consecutive frames (as if that many drones
// flew it in turn), since one source alone can never remove a tree.
nlohmann::ordered_json RunSameDay(const BenchChangesOptions& o, std::ostream& err) {
  const std::vector<MapTree> map = ToMapTrees(ReadMapTreesCsv(o.map_path));
  const auto poses = ReadPosesCsv(o.poses_path);
  const std::vector<Frame> frames = ReadFramesCsv(o.frames_path);
  algorithms::Pose3 map_from_world = algorithms::Pose3::Identity();
  if (o.truth_offset.size() == 4) {
    map_from_world = algorithms::PoseFromXyzYaw(o.truth_offset[0], o.truth_offset[1],
                                                o.truth_offset[2], o.truth_offset[3] * M_PI / 180);
  }
  algorithms::MergedMap merged;
  merged.AddSurvey(map);
  int64_t observed = 0, created = 0;
  double seconds = 0;
  for (size_t k = 0; k < frames.size(); ++k) {
    const auto pose = poses.find(frames[k].frame);
    if (pose == poses.end()) continue;
    algorithms::TimedFrame frame;
    frame.frame.source = "drone-" + std::to_string(k / static_cast<size_t>(o.source_frames));
    frame.frame.frame_id = frames[k].frame;
    frame.frame.map_from_sensor = map_from_world * pose->second;
    frame.frame.trees = frames[k].trees;
    frame.pose_sigma_xy = o.pose_sigma;
    frame.pose_sigma_yaw = o.yaw_sigma * M_PI / 180;
    frame.time = static_cast<int64_t>(k);
    const auto start = std::chrono::steady_clock::now();
    created += static_cast<int64_t>(merged.Observe(frame).merge.new_trees.size());
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ++observed;
    if (observed % 100 == 0) err << "bench-changes: " << observed << " frames\r";
  }
  err << "\n";
  int64_t max_id = 0;
  for (const MapTree& tree : map) max_id = std::max(max_id, tree.id);
  int map_removed = 0;
  for (const auto& [id, removed] : merged.removed()) map_removed += id <= max_id;
  int candidates = 0;
  for (const auto& tree : merged.Trees())
    candidates += tree.status == algorithms::TreeStatus::kCandidate;
  nlohmann::ordered_json report;
  report["map_trees"] = map.size();
  report["frames"] = observed;
  report["sources"] = (frames.size() + o.source_frames - 1) / o.source_frames;
  report["map_trees_removed"] = map_removed;
  report["map_trees_removed_share"] = Share(map_removed, static_cast<double>(map.size()));
  report["candidates_created"] = created;
  report["candidates_left"] = candidates;
  report["ms_per_frame"] = observed > 0 ? 1000 * seconds / static_cast<double>(observed) : 0.0;
  return report;
}

nlohmann::ordered_json Run(const BenchChangesOptions& o, std::ostream& err) {
  std::vector<MapTree> map = ToMapTrees(ReadMapTreesCsv(o.map_path));
  for (MapTree& tree : map) tree.position.z() = 0;  // a 2-D survey: the sensor stands at 1.5 m
  Eigen::Vector2d lo = map.front().position.head<2>(), hi = lo;
  for (const MapTree& tree : map) {
    lo = lo.cwiseMin(tree.position.head<2>());
    hi = hi.cwiseMax(tree.position.head<2>());
  }
  std::mt19937 rng(o.seed);
  const Future future = MakeFuture(map, o, lo, hi, rng);
  err << "bench-changes: " << map.size() << " trees, " << future.felled.size() << " felled, "
      << future.ingrowth.size() << " new" << std::endl;
  algorithms::MergedMap merged;
  merged.AddSurvey(map);
  const algorithms::ViewSimulator simulator(future.trees);
  algorithms::ViewOptions view;
  view.range = o.range;
  view.miss_rate = 0.1;
  view.far_miss_rate = 0.4;
  view.false_rate = o.false_rate;
  view.position_noise = 0.03;
  view.noise_per_metre = 0.002;
  std::normal_distribution<double> pose_noise(0, o.pose_sigma),
      yaw_noise(0, o.yaw_sigma * M_PI / 180);
  std::uniform_real_distribution<double> unit(0, 1);
  int64_t frame_id = 0;
  double seconds = 0;
  if (!o.write_dir.empty()) {
    std::filesystem::create_directories(o.write_dir);
    WriteChangesTruth(o.write_dir, future.felled, future.ingrowth, o.growth);
  }
  for (int pass = 0; pass < o.passes; ++pass) {
    std::optional<PassWriter> writer;
    if (!o.write_dir.empty()) writer.emplace(o.write_dir, pass);
    const bool along_x = pass % 2 == 0;
    const double offset = unit(rng) * o.line_spacing;
    const Eigen::Vector2d a = along_x ? lo : Eigen::Vector2d(lo.y(), lo.x());
    const Eigen::Vector2d b = along_x ? hi : Eigen::Vector2d(hi.y(), hi.x());
    for (double line = a.y() + offset; line <= b.y(); line += o.line_spacing) {
      for (double s = a.x(); s <= b.x(); s += o.frame_step) {
        const Eigen::Vector2d xy = along_x ? Eigen::Vector2d(s, line) : Eigen::Vector2d(line, s);
        view.seed = static_cast<unsigned>(o.seed * 1000003u + ++frame_id);
        const algorithms::SimulatedView sim = simulator.Simulate(xy, 2 * M_PI * unit(rng), view);
        algorithms::TimedFrame frame;
        frame.frame.source = "drone-" + std::to_string(pass);
        frame.frame.frame_id = frame_id;
        frame.frame.trees = sim.trees;
        // A relocalized drone's pose: the truth moved and turned by its error.
        algorithms::Pose3 pose = sim.map_from_sensor;
        pose.linear() = Eigen::AngleAxisd(yaw_noise(rng), Eigen::Vector3d::UnitZ()) * pose.linear();
        pose.translation() += Eigen::Vector3d(pose_noise(rng), pose_noise(rng), 0);
        frame.frame.map_from_sensor = pose;
        frame.pose_sigma_xy = o.pose_sigma;
        frame.pose_sigma_yaw = o.yaw_sigma * M_PI / 180;
        frame.time = frame_id;
        if (writer) writer->Add(frame.frame);
        const auto start = std::chrono::steady_clock::now();
        if (!o.no_absence) {
          merged.Observe(frame);
        } else if (!frame.frame.trees.empty()) {
          merged.Merge(frame.frame);
        }
        seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      }
    }
  }
  return Score(map, future, merged, o, frame_id, seconds);
}

}  // namespace
}  // namespace forestmap::client

namespace forestmap::client {

void AddBenchChangesCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<BenchChangesOptions>();
  CLI::App* cmd = app.add_subcommand(
      "bench-changes",
      "Simulate a stem map's future (felling, a clear-cut, ingrowth, growth), observe drone "
      "passes over it into the original map in process, and score the removals, new trees and "
      "growth against the truth");
  cmd->add_option("--map", options->map_path, "Stem map CSV (the survey)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--felled", options->felled, "Share of the trees felled at random")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--clear-cut", options->clear_cut, "Area of a disc felled entirely (ha)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--ingrowth", options->ingrowth, "New trees per original tree")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--growth", options->growth, "DBH growth of every standing tree (m)")
      ->capture_default_str();
  cmd->add_option("--passes", options->passes, "Drone passes (one source each)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--false-rate", options->false_rate, "False stems per detected tree")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--range", options->range, "Sensor range (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--line-spacing", options->line_spacing, "Distance between flight lines (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--frame-step", options->frame_step, "Distance between frames (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--pose-sigma", options->pose_sigma, "Pose error per axis, 1-sigma (m)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--yaw-sigma", options->yaw_sigma, "Heading error, 1-sigma (deg)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--seed", options->seed, "Random seed")->capture_default_str();
  cmd->add_option("--frames", options->frames_path,
                  "Real frames CSV of the same forest the same day (with --poses): observe them "
                  "into --map instead of a simulated future; every removal is wrong")
      ->check(CLI::ExistingFile);
  cmd->add_option("--poses", options->poses_path, "Ground-truth poses CSV of --frames")
      ->check(CLI::ExistingFile);
  cmd->add_option("--truth-offset", options->truth_offset,
                  "X,Y,Z,YAW_DEG: map_from_world applied to --poses (session offset)")
      ->delimiter(',')
      ->expected(4);
  cmd->add_option("--source-frames", options->source_frames,
                  "With --frames: consecutive frames per source (drone)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--reloc-views", options->reloc_views,
                  "Views of the future forest relocalized on the original and the updated map")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("--no-absence", options->no_absence,
                "Merge the frames without weighing the evidence of absence (for comparison)");
  cmd->add_option("--write", options->write_dir,
                  "Also write each pass as `forestmap observe` reads it (passK_trees.csv, "
                  "passK_poses.csv) and the truth (truth.json) into this folder");
  cmd->add_flag("--json", options->json, "Print one JSON object");
  cmd->callback([options, &context] {
    if (options->frames_path.empty() != options->poses_path.empty()) {
      throw CLI::ValidationError("--frames", "needs --poses (and the reverse)");
    }
    context.run = [options, &context] {
      const nlohmann::ordered_json report = options->frames_path.empty()
                                                ? Run(*options, *context.err)
                                                : RunSameDay(*options, *context.err);
      if (options->json) {
        *context.out << report.dump() << "\n";
        return;
      }
      for (const auto& [key, value] : report.items()) *context.out << key << ": " << value << "\n";
    };
  });
}

}  // namespace forestmap::client
