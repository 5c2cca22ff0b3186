#pragma once
// The measuring loop of `forestmap-lab bench-reloc`: one index (or a sequence of them, one per map
// of a benchmark of many small maps), every query timed in wall and CPU time, every answer
// scored against ground truth (algorithms/evaluation/reloc_evaluation.h), the report as JSON.

#include <chrono>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/relocalization/tracking.h"
#include "client/lab/cli_bench_reloc_maps.h"

namespace forestmap::client {

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
  // Simulated views: detection falling from (1 - miss) near the sensor to (1 - far miss) at the
  // range (far < 0: constant), noise of 5 cm plus this much per metre of range.
  double miss_rate = 0.3, far_miss_rate = -1, noise_per_metre = 0;
  double max_density = 0;  // trees/m^2 within the range of the sensor; > 0: only sparser views
  bool no_dbh = false;     // the maps' DBH removed (a survey of positions only)
  // --edge: the map cut by `edge_cuts` lines of random direction, views within edge_band (m)
  // of the cut; --overlap: neighbouring circular plots (plot_radius m, plot_apart m apart)
  bool edge = false, overlap = false;
  double edge_band = 8;
  int edge_cuts = 10;
  double plot_radius = 20;
  std::vector<double> plot_apart = {20, 30};
  int answerable_trees = 8;  // mapped trees in sight that make a view answerable
  bool json = false;
  bool track = false;
  std::string per_frame_path;  // CSV of every answer, for diagnosis
};

double Ms(std::chrono::steady_clock::duration d);

// One query at a time: with an optional prior drawn around the truth, timed, scored.
class Runner {
 public:
  Runner(const std::vector<algorithms::MapTree>& map, const BenchOptions& options, bool foreign);

  // The next queries go to this map (its own index), scored against it.
  void UseMap(const std::vector<algorithms::MapTree>& map);
  void Run(const std::vector<algorithms::DetectedTree>& trees, const algorithms::Pose3& truth);
  void AddDetectionTime(double ms) { detect_ms_.push_back(ms); }
  const std::vector<algorithms::MapTree>& map() const { return index_->trees(); }
  nlohmann::ordered_json Report(size_t map_trees) const;

 private:
  void AddNees(const algorithms::Pose3& truth, const algorithms::RelocalizeResult& result);
  Eigen::Vector3d NoisyGravity(const algorithms::Pose3& map_from_sensor);
  void WriteRow(bool answerable, int mapped, const algorithms::Pose3& truth,
                const algorithms::RelocalizeResult& result, double ms, double cpu_ms);
  algorithms::RelocalizeResult Track(const algorithms::RelocalizeQuery& query);

  const BenchOptions& options_;
  algorithms::RelocEvaluator evaluator_;
  std::optional<algorithms::Tracker> tracker_;
  int track_counts_[3] = {0, 0, 0};  // by TrackState
  int longest_loss_ = 0;
  int frames_ = 0, within_ = 0, maps_ = 0;
  std::vector<double> detect_ms_;  // per scan (--scans)
  std::vector<double> nees_;       // per correct LOCALIZED answer
  std::vector<double> cpu_ms_;     // per query
  std::unique_ptr<algorithms::MapIndex> index_;
  std::mt19937 rng_;
  bool foreign_ = false;  // the views come from another forest than the index's
  double build_ms_ = 0;
  double index_resident_ = 0;  // growth of the resident set while the index was built (bytes)
  std::ofstream per_frame_;
};

}  // namespace forestmap::client
