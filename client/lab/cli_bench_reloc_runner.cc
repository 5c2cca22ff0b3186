#include "client/lab/cli_bench_reloc_runner.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <iomanip>

#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

using algorithms::Pose3;

double Mean(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v;
  return values.empty() ? 0.0 : sum / values.size();
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

algorithms::RelocCriteria Criteria(const BenchOptions& options) {
  algorithms::RelocCriteria criteria;
  criteria.answerable_min_trees = options.answerable_trees;
  return criteria;
}

}  // namespace

double Ms(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

Runner::Runner(const std::vector<algorithms::MapTree>& map, const BenchOptions& options,
               bool foreign)
    : options_(options),
      evaluator_(map, Criteria(options)),
      rng_(options.maps.seed),
      foreign_(foreign) {
  if (!options.per_frame_path.empty()) {
    per_frame_.open(options.per_frame_path);
    if (!per_frame_) throw CommandError("cannot write " + options.per_frame_path);
    per_frame_ << "query,answerable,status,x,y,yaw_deg,true_x,true_y,true_yaw_deg,error_xy_m,"
                  "error_yaw_deg,inliers,confidence,ms,cpu_ms,hypotheses,triangles,poses_checked,"
                  "mapped_in_sight,map,reason,detail\n";
  }
  UseMap(map);
  if (options.track) tracker_.emplace();
}

void Runner::UseMap(const std::vector<algorithms::MapTree>& map) {
  index_.reset();
  const size_t resident_before = ResidentBytes();
  const auto start = std::chrono::steady_clock::now();
  index_ = std::make_unique<algorithms::MapIndex>(map);
  build_ms_ += Ms(std::chrono::steady_clock::now() - start);
  if (maps_ == 0) index_resident_ = static_cast<double>(ResidentBytes()) - resident_before;
  if (maps_ > 0) evaluator_.UseMap(map);
  ++maps_;
}

void Runner::Run(const std::vector<algorithms::DetectedTree>& trees, const Pose3& truth) {
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
  const int mapped = foreign_ ? 0 : evaluator_.MappedInSight(trees, truth);
  const bool answerable = !foreign_ && mapped >= options_.answerable_trees;
  evaluator_.Add(answerable, truth, result, ms, mapped);
  if (per_frame_.is_open()) WriteRow(answerable, mapped, truth, result, ms, cpu_ms);
  AddNees(truth, result);
  cpu_ms_.push_back(cpu_ms);
  ++frames_;
  within_ += result.status == algorithms::RelocalizeStatus::kLocalized &&
             algorithms::ComparePoses(result.map_from_sensor, truth).xy <= options_.within;
}

// Normalised squared error of a correct LOCALIZED answer in (x, y, yaw) under its covariance
// (3 degrees of freedom: a calibrated covariance gives a mean of 3).
void Runner::AddNees(const Pose3& truth, const algorithms::RelocalizeResult& result) {
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

nlohmann::ordered_json Runner::Report(size_t map_trees) const {
  algorithms::RelocSummary s = evaluator_.Summary();
  if (foreign_) {
    s.wrong = s.localized;
    s.wrong_rate = s.frames ? double(s.wrong) / s.frames : 0.0;
  }
  return {{"map_trees", map_trees},
          {"maps", maps_},
          {"index_build_ms", build_ms_ / std::max(1, maps_)},
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
          {"rich_views", s.rich},
          {"rich_recall", s.rich_recall},
          {"wrong", s.wrong},
          {"wrong_rate", s.wrong_rate},
          {"error_xy_p50_m", s.error_xy_p50},
          {"error_xy_p95_m", s.error_xy_p95},
          {"error_yaw_p50_deg", s.error_yaw_p50},
          {"time_p50_ms", s.time_p50},
          {"time_p95_ms", s.time_p95},
          {"time_p99_ms", s.time_p99},
          {"time_max_ms", s.time_max},
          {"cpu_p50_ms", algorithms::Percentile(cpu_ms_, 0.5)},
          {"cpu_p95_ms", algorithms::Percentile(cpu_ms_, 0.95)},
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

// Gravity (down) in the sensor frame as an IMU reports it: the truth, tilted about a random
// horizontal axis by a Gaussian angle of imu_noise RMS.
Eigen::Vector3d Runner::NoisyGravity(const Pose3& map_from_sensor) {
  std::normal_distribution<double> angle(0, options_.imu_noise * M_PI / 180);
  std::uniform_real_distribution<double> direction(-M_PI, M_PI);
  const double a = direction(rng_);
  const Eigen::AngleAxisd tilt(angle(rng_), Eigen::Vector3d(std::cos(a), std::sin(a), 0));
  return map_from_sensor.linear().transpose() * (tilt * Eigen::Vector3d(0, 0, -1));
}

void Runner::WriteRow(bool answerable, int mapped, const Pose3& truth,
                      const algorithms::RelocalizeResult& result, double ms, double cpu_ms) {
  const bool localized = result.status == algorithms::RelocalizeStatus::kLocalized;
  const algorithms::PoseError error = algorithms::ComparePoses(result.map_from_sensor, truth);
  const Eigen::Vector3d t = result.map_from_sensor.translation(), u = truth.translation();
  char row[400];
  std::snprintf(
      row, sizeof row,
      "%d,%d,%s,%.3f,%.3f,%.2f,%.3f,%.3f,%.2f,%.3f,%.3f,%d,%.3f,%.3f,%.3f,%d,%d,%lld,%d,%d,"
      "%s,",
      frames_, answerable ? 1 : 0, algorithms::ToString(result.status), localized ? t.x() : NAN,
      localized ? t.y() : NAN,
      localized ? algorithms::YawOf(result.map_from_sensor.linear()) * 180 / M_PI : NAN, u.x(),
      u.y(), algorithms::YawOf(truth.linear()) * 180 / M_PI, localized ? error.xy : NAN,
      localized ? error.yaw : NAN, result.inliers, result.confidence, ms, cpu_ms, result.hypotheses,
      result.triangles, static_cast<long long>(result.poses_checked), mapped, maps_ - 1,
      algorithms::ToString(result.reason));
  per_frame_ << row << std::quoted(result.detail, '"', '"') << "\n";
}

algorithms::RelocalizeResult Runner::Track(const algorithms::RelocalizeQuery& query) {
  const algorithms::TrackingStep step = tracker_->Step(*index_, {query, std::nullopt});
  ++track_counts_[static_cast<int>(step.state)];
  longest_loss_ = std::max(longest_loss_, step.frames_lost);
  return step.result;
}

}  // namespace forestmap::client
