// forestmap-lab bench-reloc: relocalization accuracy and latency against ground truth, in process.
//
// Real sequences:  --map MAP.csv --frames trees.csv --poses poses.csv [--truth-offset ...]
// Simulated views: --map STEMMAP.csv --simulate N [--range M]   (views drawn from the map)
// Scans:           --map MAP.csv --scans DIR (from `forestmap-lab simulate`: DIR/poses.csv and
//                  DIR/scan_NNN.pcd): each scan goes through the client's trunk detection
//                  (client/lib/scan_trees.h) and is relocalized, as `relocalize --scan` does
// Tracking:        --track with real frames: frames in order through one tracking session
//                  (algorithms/relocalization/tracking.h), each frame's answer scored like a
//                  relocalization
// Generated maps:  --generate N --like STEMMAP.csv --simulate N (a forest with the real map's
//                  spatial statistics, e.g. 1,000,000 trees)
// District cases:  --mosaic A.csv,B.csv,... or --plantation SX,SY,ERROR,MORTALITY with
//                  --simulate N; --foreign (another seed's map) or --foreign-map B.csv
//                  relocalizes the views in another forest (cli_bench_reloc_maps.h)
// Views that see beyond their map: --edge, --overlap (cli_bench_reloc_cases.h)
// Prints recall, strict recall, wrong answers, error and latency percentiles (the definitions
// are in algorithms/evaluation/reloc_evaluation.h), as text or one JSON object (--json).

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "algorithms/core/kdtree.h"
#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "client/lab/cli_bench_reloc_cases.h"
#include "client/lab/cli_bench_reloc_maps.h"
#include "client/lab/cli_bench_reloc_runner.h"
#include "client/lab/lab_commands.h"
#include "client/lib/scan_trees.h"

namespace forestmap::client {
namespace {

using algorithms::Pose3;

// Two sessions' ground truths of one forest agree only up to a drift of ~0.1-0.2 m that varies
// along the route (see ../shared/data/README.md). The offset at a place: the median
// displacement from the frames' own session map (moved by map_from_world) to the map
// relocalized against, over the tree pairs within kRadius of it. Uses the two maps only.
class LocalMapOffset {
 public:
  LocalMapOffset(const std::vector<algorithms::MapTree>& map,
                 const std::vector<algorithms::MapTree>& session_map, const Pose3& map_from_world) {
    std::vector<algorithms::KdTree<double, 2>::Point> xy;
    for (const auto& t : map) xy.push_back({t.position.x(), t.position.y()});
    map_xy_ = std::make_unique<algorithms::KdTree<double, 2>>(std::move(xy));
    std::vector<algorithms::KdTree<double, 2>::Point> session_xy;
    for (const auto& t : session_map) {
      const Eigen::Vector3d p = map_from_world * t.position;
      session_.push_back(p.head<2>());
      session_xy.push_back({p.x(), p.y()});
    }
    session_xy_ = std::make_unique<algorithms::KdTree<double, 2>>(std::move(session_xy));
  }

  Eigen::Vector2d At(const Eigen::Vector3d& position) const {
    constexpr double kRadius = 20.0, kPairDistance = 0.5;  // m
    std::vector<std::pair<uint32_t, double>> found;
    session_xy_->Radius({position.x(), position.y()}, kRadius, found);
    std::vector<double> dx, dy;
    for (const auto& [i, d2] : found) {
      const auto [j, e2] = map_xy_->Nearest({session_[i].x(), session_[i].y()});
      if (j < 0 || e2 > kPairDistance * kPairDistance) continue;
      dx.push_back(map_xy_->point(j)[0] - session_[i].x());
      dy.push_back(map_xy_->point(j)[1] - session_[i].y());
    }
    if (dx.size() < 5) return Eigen::Vector2d::Zero();
    return {algorithms::Percentile(dx, 0.5), algorithms::Percentile(dy, 0.5)};
  }

 private:
  std::unique_ptr<algorithms::KdTree<double, 2>> map_xy_, session_xy_;
  std::vector<Eigen::Vector2d> session_;
};

void RunSequence(Runner& runner, const BenchOptions& o, std::ostream& err) {
  const auto poses = ReadPosesCsv(o.poses_path);
  const auto frames = ReadFramesCsv(o.frames_path);
  Pose3 map_from_world = Pose3::Identity();
  if (!o.truth_offset.empty()) {
    map_from_world = algorithms::PoseFromXyzYaw(o.truth_offset[0], o.truth_offset[1],
                                                o.truth_offset[2], o.truth_offset[3] * M_PI / 180);
  }
  std::optional<LocalMapOffset> local_offset;
  if (!o.truth_map_path.empty()) {
    local_offset.emplace(runner.map(), ToMapTrees(ReadMapTreesCsv(o.truth_map_path)),
                         map_from_world);
  }
  std::vector<size_t> chosen;
  for (size_t i = 0; i < frames.size(); i += o.step) {
    if (o.limit > 0 && chosen.size() >= static_cast<size_t>(o.limit)) break;
    chosen.push_back(i);
  }
  for (size_t k = 0; k < chosen.size(); ++k) {
    const Frame& frame = frames[chosen[k]];
    const auto pose = poses.find(frame.frame);
    if (pose == poses.end()) {
      throw CommandError(o.poses_path + ": no pose for frame " + std::to_string(frame.frame));
    }
    Pose3 truth = map_from_world * pose->second;
    if (local_offset) truth.translation().head<2>() += local_offset->At(truth.translation());
    runner.Run(frame.trees, truth);
    LabProgress(err, "bench-reloc", k + 1, chosen.size(), 200);
  }
}

void RunScans(Runner& runner, const BenchOptions& o, std::ostream& err) {
  const auto poses = ReadPosesCsv(o.scans_dir + "/poses.csv");
  size_t done = 0;
  for (const auto& [frame, truth] : poses) {
    char name[32];
    std::snprintf(name, sizeof name, "/scan_%03lld.pcd", static_cast<long long>(frame));
    const ScanTrees scan = DetectScanTrees(o.scans_dir + name);
    runner.AddDetectionTime(scan.stats.total_us / 1000.0);
    runner.Run(scan.trees, truth);
    LabProgress(err, "bench-reloc", ++done, poses.size(), 200);
  }
}

void RunSimulated(const std::vector<algorithms::MapTree>& map, Runner& runner,
                  const BenchOptions& o, std::ostream& err) {
  algorithms::ViewSimulator simulator(map);
  algorithms::ViewOptions view = ViewModel(o, o.range);
  // Keep the sensor a range away from the plot's border, or a quarter of a small plot.
  const Eigen::Vector2d size = simulator.grid().max_corner() - simulator.grid().min_corner();
  const double margin = std::min(o.range, 0.25 * size.minCoeff());
  const auto poses =
      o.max_density > 0
          ? SampleViewPoses(simulator, o.simulate, margin, o.maps.seed, o.range,
                            [&](const Eigen::Vector3d& p) {
                              return simulator.grid().InRadius(p.head<2>(), o.range).size() <
                                     o.max_density * M_PI * o.range * o.range;
                            })
          : simulator.SamplePoses(o.simulate, margin, o.maps.seed, 8, o.range);
  if (poses.empty()) {
    err << "bench-reloc: no place in the map where the sensor sees 8 trees within " << o.range
        << " m\n";
  }
  for (size_t i = 0; i < poses.size(); ++i) {
    view.seed = o.maps.seed * 100003u + static_cast<unsigned>(i);
    const algorithms::SimulatedView v = simulator.Simulate(poses[i].head<2>(), poses[i].z(), view);
    runner.Run(v.trees, v.map_from_sensor);
    LabProgress(err, "bench-reloc", i + 1, poses.size(), 200);
  }
}

void Run(const BenchOptions& o, CliContext& context) {
  const BenchMaps maps = LoadBenchMaps(o.maps, *context.err);
  const std::vector<algorithms::MapTree>& map = maps.index;
  nlohmann::ordered_json report;
  if (o.edge || o.overlap) {
    report = RunCoverageCase(maps.views, o, *context.err);
  } else {
    *context.err << "bench-reloc: building the index of " << map.size() << " trees" << std::endl;
    Runner runner(map, o, maps.foreign);
    *context.err << "bench-reloc: index built" << std::endl;
    if (o.simulate > 0) {
      RunSimulated(maps.views, runner, o, *context.err);
    } else if (!o.scans_dir.empty()) {
      RunScans(runner, o, *context.err);
    } else {
      RunSequence(runner, o, *context.err);
    }
    report = runner.Report(map.size());
  }
  if (o.json) {
    *context.out << report.dump() << "\n";
    return;
  }
  for (const auto& [key, value] : report.items()) *context.out << key << ": " << value << "\n";
}

}  // namespace

void AddBenchRelocCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<BenchOptions>();
  CLI::App* cmd = app.add_subcommand(
      "bench-reloc",
      "Measure relocalization against ground truth, in process: real frames with poses, "
      "simulated views of a stem map, or a generated map of any size");
  AddBenchMapOptions(cmd, options->maps);
  cmd->add_option("--frames", options->frames_path, "Frames CSV (frame,x,y,z,...), sensor frame")
      ->check(CLI::ExistingFile);
  cmd->add_option("--poses", options->poses_path,
                  "Ground-truth poses CSV (frame,timestamp,x,y,z,qx,qy,qz,qw)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--truth-offset", options->truth_offset,
                  "X,Y,Z,YAW_DEG: map_from_world applied to the poses (session offset)")
      ->delimiter(',')
      ->expected(4);
  cmd->add_option("--truth-map", options->truth_map_path,
                  "The frames' own session map: align the truth locally to --map (median offset "
                  "of the two maps' trees within 20 m), for sessions whose ground truths drift "
                  "apart")
      ->check(CLI::ExistingFile);
  cmd->add_option("--step", options->step, "Use every N-th frame")->check(CLI::PositiveNumber);
  cmd->add_option("--limit", options->limit, "At most N frames (0 = all)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--prior-noise", options->prior_noise,
                  "Give a prior: the true position plus Gaussian noise of this RMS (m)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--prior-radius", options->prior_radius, "Search radius of the prior (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--imu-noise", options->imu_noise,
                  "Queries carry gravity as an IMU gives it: the true one tilted by this RMS (deg)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--simulate", options->simulate, "Relocalize N simulated views of the map")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--range", options->range, "Simulated sensor range (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--seed", options->maps.seed, "Random seed")->capture_default_str();
  cmd->add_option(
         "--scans", options->scans_dir,
         "Folder from `forestmap-lab simulate` (poses.csv, scan_NNN.pcd): detect the trunks "
         "of every scan, then relocalize")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--within", options->within,
                  "Also report the share of all frames localized within this distance (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_flag("--track", options->track,
                "Track the frames in order (one tracking session) instead of relocalizing each");
  AddCoverageCaseOptions(cmd, *options);
  cmd->add_flag("--json", options->json, "Print one JSON object");
  cmd->add_option("--per-frame", options->per_frame_path,
                  "Also write every answer with its error and time to this CSV");
  cmd->callback([options, &context] {
    const BenchOptions& o = *options;
    CheckBenchMapOptions(o.maps, o.simulate > 0);
    if ((o.edge || o.overlap) &&
        (o.maps.map_path.empty() || o.simulate == 0 || o.edge == o.overlap ||
         !o.maps.foreign_map_path.empty() || o.track || o.prior_noise >= 0)) {
      throw CLI::ValidationError("--edge",
                                 "--edge or --overlap needs --map STEMMAP.csv and "
                                 "--simulate N, without --foreign-map, --track or a prior");
    }
    if (o.simulate == 0 && o.scans_dir.empty() && (o.frames_path.empty() || o.poses_path.empty())) {
      throw CLI::ValidationError(
          "--frames", "real frames need --frames and --poses (or use --simulate N or --scans DIR)");
    }
    context.run = [options, &context] { Run(*options, context); };
  });
}

}  // namespace forestmap::client
