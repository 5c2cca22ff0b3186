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
// Prints recall, strict recall, wrong answers, error and latency percentiles (the definitions
// are in algorithms/evaluation/reloc_evaluation.h), as text or one JSON object (--json).

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <random>

#include "algorithms/core/kdtree.h"
#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/relocalization/tracking.h"
#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "client/lab/cli_bench_reloc_maps.h"
#include "client/lab/lab_commands.h"
#include "client/lib/scan_trees.h"

namespace forestmap::client {
namespace {

using algorithms::Pose3;

struct BenchOptions {
  BenchMapOptions maps;  // --map, --generate, --mosaic, --plantation, --foreign..., --seed
  std::string frames_path, poses_path, scans_dir;
  double within = 0.3;               // m, also report the share of all frames localized this close
  std::vector<double> truth_offset;  // x, y, z (m), yaw (deg): map_from_world of the poses
  std::string truth_map_path;        // the frames' own session map, for local truth alignment
  int step = 1, limit = 0;
  double prior_noise = -1, prior_radius = 10;  // m; prior_noise < 0: no prior
  double imu_noise = -1;  // deg; >= 0: queries carry gravity, the truth's tilted by this RMS
  int simulate = 0;
  double range = 15;
  bool json = false;
  bool track = false;
  std::string per_frame_path;  // CSV of every answer, for diagnosis
};

double Mean(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v;
  return values.empty() ? 0.0 : sum / values.size();
}

double Ms(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

// Resident set size of this process (bytes; Linux /proc/self/statm), 0 when unknown.
size_t ResidentBytes() {
  std::ifstream statm("/proc/self/statm");
  size_t pages = 0, resident = 0;
  if (!(statm >> pages >> resident)) return 0;
  return resident * static_cast<size_t>(sysconf(_SC_PAGESIZE));
}

// CPU time of the calling thread (ms): per-query cost even while other work shares the cores.
double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec * 1e3 + t.tv_nsec / 1e6;
}

// One query: with an optional prior drawn around the truth, timed, scored.
class Runner {
 public:
  Runner(const std::vector<algorithms::MapTree>& map, const BenchOptions& options, bool foreign)
      : options_(options), evaluator_(map), rng_(options.maps.seed), foreign_(foreign) {
    if (!options.per_frame_path.empty()) {
      per_frame_.open(options.per_frame_path);
      if (!per_frame_) throw CommandError("cannot write " + options.per_frame_path);
      per_frame_ << "query,answerable,status,x,y,yaw_deg,true_x,true_y,true_yaw_deg,error_xy_m,"
                    "error_yaw_deg,inliers,confidence,ms,cpu_ms,hypotheses,triangles,poses_checked,"
                    "detail\n";
    }
    const size_t resident_before = ResidentBytes();
    const auto start = std::chrono::steady_clock::now();
    index_ = std::make_unique<algorithms::MapIndex>(map);
    build_ms_ = Ms(std::chrono::steady_clock::now() - start);
    index_resident_ = static_cast<double>(ResidentBytes()) - resident_before;
    if (options.track) tracker_.emplace();
  }

  void Run(const std::vector<algorithms::DetectedTree>& trees, const Pose3& truth) {
    algorithms::RelocalizeQuery query;
    query.trees = trees;
    if (options_.prior_noise >= 0) {
      std::normal_distribution<double> noise(0, options_.prior_noise / std::sqrt(2.0));
      algorithms::PriorPose prior;
      prior.map_from_sensor = truth;
      prior.map_from_sensor.translation() += Eigen::Vector3d(noise(rng_), noise(rng_), 0);
      prior.radius = options_.prior_radius;
      query.prior = prior;
    }
    if (options_.imu_noise >= 0) query.gravity = NoisyGravity(truth);
    const double cpu_start = ThreadCpuMs();
    const auto start = std::chrono::steady_clock::now();
    const algorithms::RelocalizeResult result =
        tracker_ ? Track(query) : algorithms::Relocalize(*index_, query);
    const double ms = Ms(std::chrono::steady_clock::now() - start);
    const double cpu_ms = ThreadCpuMs() - cpu_start;
    // In a foreign map no frame is answerable and every LOCALIZED answer is wrong.
    const bool answerable = !foreign_ && evaluator_.Answerable(trees, truth);
    evaluator_.Add(answerable, truth, result, ms);
    if (per_frame_.is_open()) WriteRow(answerable, truth, result, ms, cpu_ms);
    AddNees(truth, result);
    ++frames_;
    within_ += result.status == algorithms::RelocalizeStatus::kLocalized &&
               algorithms::ComparePoses(result.map_from_sensor, truth).xy <= options_.within;
  }

  void AddDetectionTime(double ms) { detect_ms_.push_back(ms); }

  // Normalised squared error of a correct LOCALIZED answer in (x, y, yaw) under its covariance
  // (3 degrees of freedom: a calibrated covariance gives a mean of 3).
  void AddNees(const Pose3& truth, const algorithms::RelocalizeResult& result) {
    const algorithms::PoseError error = algorithms::ComparePoses(result.map_from_sensor, truth);
    if (result.status != algorithms::RelocalizeStatus::kLocalized || error.xy > 0.5 ||
        error.yaw > 5.0) {
      return;
    }
    Eigen::Vector3d e;
    e.head<2>() = (result.map_from_sensor.translation() - truth.translation()).head<2>();
    e.z() = algorithms::WrapAngle(algorithms::YawOf(result.map_from_sensor.linear()) -
                                  algorithms::YawOf(truth.linear()));
    const int index[3] = {0, 1, 5};
    Eigen::Matrix3d cov;
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) cov(a, b) = result.covariance(index[a], index[b]);
    }
    nees_.push_back(e.dot(cov.ldlt().solve(e)));
  }
  const std::vector<algorithms::MapTree>& map() const { return index_->trees(); }

  nlohmann::ordered_json Report(size_t map_trees) const {
    algorithms::RelocSummary s = evaluator_.Summary();
    if (foreign_) {
      s.wrong = s.localized;
      s.wrong_rate = s.frames ? double(s.wrong) / s.frames : 0.0;
    }
    return {{"map_trees", map_trees},
            {"index_build_ms", build_ms_},
            {"index_triangle_side_m", index_->triangle_side()},
            {"index_levels", nlohmann::json(index_->triangle_levels())},  // [side m, count]
            {"index_bytes_per_tree", map_trees ? double(index_->MemoryBytes()) / map_trees : 0},
            {"index_resident_bytes_per_tree", map_trees ? index_resident_ / map_trees : 0},
            {"foreign_map", foreign_},
            {"frames", s.frames},
            {"answerable", s.answerable},
            {"localized", s.localized},
            {"ambiguous", s.ambiguous},
            {"not_found", s.not_found},
            {"recall", s.recall},
            {"strict_recall", s.strict_recall},
            {"wrong", s.wrong},
            {"wrong_rate", s.wrong_rate},
            {"error_xy_p50_m", s.error_xy_p50},
            {"error_xy_p95_m", s.error_xy_p95},
            {"error_yaw_p50_deg", s.error_yaw_p50},
            {"time_p50_ms", s.time_p50},
            {"time_p95_ms", s.time_p95},
            {"time_p99_ms", s.time_p99},
            {"time_max_ms", s.time_max},
            {"localized_within", options_.within},
            {"localized_within_rate", frames_ ? double(within_) / frames_ : 0.0},
            {"track_local", track_counts_[0]},
            {"track_recovered", track_counts_[1]},
            {"track_lost", track_counts_[2]},
            {"track_longest_loss_frames", longest_loss_},
            {"nees_xy_yaw_mean", Mean(nees_)},
            {"nees_xy_yaw_median", algorithms::Percentile(nees_, 0.5)},
            {"nees_dof", 3},
            {"detect_p50_ms", algorithms::Percentile(detect_ms_, 0.5)},
            {"detect_p95_ms", algorithms::Percentile(detect_ms_, 0.95)}};
  }

 private:
  // Gravity (down) in the sensor frame as an IMU reports it: the truth, tilted about a random
  // horizontal axis by a Gaussian angle of imu_noise RMS.
  Eigen::Vector3d NoisyGravity(const Pose3& map_from_sensor) {
    std::normal_distribution<double> angle(0, options_.imu_noise * M_PI / 180);
    std::uniform_real_distribution<double> direction(-M_PI, M_PI);
    const double a = direction(rng_);
    const Eigen::AngleAxisd tilt(angle(rng_), Eigen::Vector3d(std::cos(a), std::sin(a), 0));
    return map_from_sensor.linear().transpose() * (tilt * Eigen::Vector3d(0, 0, -1));
  }

  void WriteRow(bool answerable, const Pose3& truth, const algorithms::RelocalizeResult& result,
                double ms, double cpu_ms) {
    const bool localized = result.status == algorithms::RelocalizeStatus::kLocalized;
    const algorithms::PoseError error = algorithms::ComparePoses(result.map_from_sensor, truth);
    const Eigen::Vector3d t = result.map_from_sensor.translation(), u = truth.translation();
    char row[400];
    std::snprintf(row, sizeof row,
                  "%d,%d,%s,%.3f,%.3f,%.2f,%.3f,%.3f,%.2f,%.3f,%.3f,%d,%.3f,%.3f,%.3f,%d,%d,%lld,",
                  frames_, answerable ? 1 : 0, algorithms::ToString(result.status),
                  localized ? t.x() : NAN, localized ? t.y() : NAN,
                  localized ? algorithms::YawOf(result.map_from_sensor.linear()) * 180 / M_PI : NAN,
                  u.x(), u.y(), algorithms::YawOf(truth.linear()) * 180 / M_PI,
                  localized ? error.xy : NAN, localized ? error.yaw : NAN, result.inliers,
                  result.confidence, ms, cpu_ms, result.hypotheses, result.triangles,
                  static_cast<long long>(result.poses_checked));
    per_frame_ << row << std::quoted(result.detail, '"', '"') << "\n";
  }

  algorithms::RelocalizeResult Track(const algorithms::RelocalizeQuery& query) {
    const algorithms::TrackingStep step = tracker_->Step(*index_, {query, std::nullopt});
    ++track_counts_[static_cast<int>(step.state)];
    longest_loss_ = std::max(longest_loss_, step.frames_lost);
    return step.result;
  }

  const BenchOptions& options_;
  algorithms::RelocEvaluator evaluator_;
  std::optional<algorithms::Tracker> tracker_;
  int track_counts_[3] = {0, 0, 0};  // by TrackState
  int longest_loss_ = 0;
  int frames_ = 0, within_ = 0;
  std::vector<double> detect_ms_;  // per scan (--scans)
  std::vector<double> nees_;       // per correct LOCALIZED answer
  std::unique_ptr<algorithms::MapIndex> index_;
  std::mt19937 rng_;
  bool foreign_ = false;  // the views come from another forest than the index's
  double build_ms_ = 0;
  double index_resident_ = 0;  // growth of the resident set while the index was built (bytes)
  std::ofstream per_frame_;
};

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

void Progress(std::ostream& err, size_t done, size_t total) {
  if (done % 200 == 0 || done == total) err << "bench-reloc: " << done << "/" << total << "\r";
  if (done == total) err << "\n";
}

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
    Progress(err, k + 1, chosen.size());
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
    Progress(err, ++done, poses.size());
  }
}

void RunSimulated(const std::vector<algorithms::MapTree>& map, Runner& runner,
                  const BenchOptions& o, std::ostream& err) {
  algorithms::ViewSimulator simulator(map);
  algorithms::ViewOptions view;  // occlusion, 30% misses, 20% false stems, 5 cm noise
  view.range = o.range;
  // Keep the sensor a range away from the plot's border, or a quarter of a small plot.
  const Eigen::Vector2d size = simulator.grid().max_corner() - simulator.grid().min_corner();
  const double margin = std::min(o.range, 0.25 * size.minCoeff());
  const auto poses = simulator.SamplePoses(o.simulate, margin, o.maps.seed, 8, o.range);
  if (poses.empty()) {
    err << "bench-reloc: no place in the map where the sensor sees 8 trees within " << o.range
        << " m\n";
  }
  for (size_t i = 0; i < poses.size(); ++i) {
    view.seed = o.maps.seed * 100003u + static_cast<unsigned>(i);
    const algorithms::SimulatedView v = simulator.Simulate(poses[i].head<2>(), poses[i].z(), view);
    runner.Run(v.trees, v.map_from_sensor);
    Progress(err, i + 1, poses.size());
  }
}

void Run(const BenchOptions& o, CliContext& context) {
  const BenchMaps maps = LoadBenchMaps(o.maps, *context.err);
  const std::vector<algorithms::MapTree>& map = maps.index;
  Runner runner(map, o, maps.foreign);
  if (o.simulate > 0) {
    RunSimulated(maps.views, runner, o, *context.err);
  } else if (!o.scans_dir.empty()) {
    RunScans(runner, o, *context.err);
  } else {
    RunSequence(runner, o, *context.err);
  }
  const nlohmann::ordered_json report = runner.Report(map.size());
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
  cmd->add_flag("--json", options->json, "Print one JSON object");
  cmd->add_option("--per-frame", options->per_frame_path,
                  "Also write every answer with its error and time to this CSV");
  cmd->callback([options, &context] {
    const BenchOptions& o = *options;
    CheckBenchMapOptions(o.maps, o.simulate > 0);
    if (o.simulate == 0 && o.scans_dir.empty() && (o.frames_path.empty() || o.poses_path.empty())) {
      throw CLI::ValidationError(
          "--frames", "real frames need --frames and --poses (or use --simulate N or --scans DIR)");
    }
    context.run = [options, &context] { Run(*options, context); };
  });
}

}  // namespace forestmap::client
