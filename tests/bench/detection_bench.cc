// Trunk detection speed, scan to tree list, on one core: simulated drone scans of a generated
// forest (shrubs, crowns, branches, sloped terrain) from a 128 x 2048 scanner (262k points, bar
// <= 50 ms median) and a 32 x 1024 scanner (bar <= 10 ms median). Run:
//   build/tests/bench/detection_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include <string>

#include "algorithms/detection/trunk_detection.h"
#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/scan_simulation.h"

namespace forestmap::algorithms {
namespace {

ScanSimulationResult DroneScan(const std::string& scanner_name) {
  StemMapStatistics stats;
  stats.density = 0.06;  // trees per m^2 (600 per ha)
  stats.min_spacing = 1.5;
  ForestOptions forest;
  forest.width = forest.height = 80;
  forest.seed = 3;
  const ForestScene scene(GenerateForest(stats, forest), SceneOptions{});
  const Pose3 pose = DronePose(scene, 40, 40, 6.0, 0.3, 0.03, -0.02);
  ScanNoiseOptions noise;
  noise.threads = 2;
  return SimulateScan(scene, pose, ScannerPreset(scanner_name), noise, 11);
}

void BM_DetectTrunks(benchmark::State& state, const std::string& scanner_name) {
  const ScanSimulationResult scan = DroneScan(scanner_name);
  TrunkDetectionOptions options;
  options.stem.beam_divergence = 3.1e-3;
  size_t trees = 0;
  TrunkDetectionStats stats;
  for (auto _ : state) {
    const TrunkDetectionResult result = DetectTrunks(scan.cloud, options);
    trees = result.trees.size();
    stats = result.stats;
    benchmark::DoNotOptimize(trees);
  }
  state.counters["points"] = static_cast<double>(scan.cloud.size());
  state.counters["returns"] = scan.returns;
  state.counters["trees"] = static_cast<double>(trees);
  state.counters["layer_pts"] = static_cast<double>(stats.stem_layer_points);
  state.counters["clusters"] = static_cast<double>(stats.clusters);
  state.counters["chains"] = static_cast<double>(stats.candidates);
  state.counters["ground_ms"] = stats.ground_us / 1000.0;
  state.counters["cluster_ms"] = stats.cluster_us / 1000.0;
  state.counters["fit_ms"] = stats.fit_us / 1000.0;
}

BENCHMARK_CAPTURE(BM_DetectTrunks, os0_128x2048, std::string("os0-128"))
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DetectTrunks, os1_128x2048, std::string("os1-128"))
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DetectTrunks, os0_32x1024, std::string("os0-32-1024"))
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DetectTrunks, os1_32x1024, std::string("os1-32-1024"))
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace forestmap::algorithms

BENCHMARK_MAIN();
