#pragma once
// The cases of `forestmap-lab bench-reloc` whose views see more forest than the map they are
// relocalized in (algorithms/evaluation/coverage_cases.h), and the simulated views' model:
//   --edge     the stem map cut by --edge-cuts lines of random direction (each cut its own
//              map: the trees on one side), --simulate N views in all, simulated in the whole
//              forest within --edge-band m of the cut
//   --overlap  --simulate N pairs of neighbouring circular plots (--plot-radius m, centres
//              --plot-apart MIN,MAX m apart): a view from one plot's centre (range: the plot
//              radius) relocalized in the other plot's map
// and, for any simulated views, --max-density (only views in stands sparser than this).

#include <CLI/CLI.hpp>
#include <functional>
#include <ostream>
#include <vector>

#include "algorithms/simulation/view_simulator.h"
#include "client/lab/cli_bench_reloc_runner.h"

namespace forestmap::client {

void AddCoverageCaseOptions(CLI::App* cmd, BenchOptions& options);

// The simulated views' model from the options (occlusion, misses, false stems, noise).
algorithms::ViewOptions ViewModel(const BenchOptions& options, double range);

// `count` view poses (x, y, yaw) of the forest at least `margin` m inside its extent with 8
// trees within `range`, each passing `keep` (draws in batches; fewer when the forest has too
// few such places).
std::vector<Eigen::Vector3d> SampleViewPoses(
    const algorithms::ViewSimulator& simulator, int count, double margin, unsigned seed,
    double range, const std::function<bool(const Eigen::Vector3d&)>& keep);

// Runs --edge or --overlap over `forest` and returns the report.
nlohmann::ordered_json RunCoverageCase(const std::vector<algorithms::MapTree>& forest,
                                       const BenchOptions& options, std::ostream& err);

}  // namespace forestmap::client
