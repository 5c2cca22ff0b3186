#include "client/lab/cli_bench_reloc_cases.h"

#include <functional>
#include <random>

#include "algorithms/evaluation/coverage_cases.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

using algorithms::MapTree;

// A map as searched: without DBH with --no-dbh.
std::vector<MapTree> Searched(std::vector<MapTree> map, const BenchOptions& o) {
  if (o.maps.no_dbh) {
    for (MapTree& t : map) t.dbh = algorithms::kUnknown;
  }
  return map;
}

// Views within the band of each cut, every cut its own map; the views in the whole forest.
nlohmann::ordered_json RunEdge(const std::vector<MapTree>& forest, const BenchOptions& o,
                               std::ostream& err) {
  const algorithms::ViewSimulator simulator(forest);
  const Eigen::Vector2d lo = simulator.grid().min_corner(), hi = simulator.grid().max_corner();
  const double margin = std::min(o.range, 0.25 * (hi - lo).minCoeff());
  std::mt19937 rng(o.maps.seed);
  std::optional<Runner> runner;
  int done = 0;
  for (int cut = 0; cut < o.edge_cuts; ++cut) {
    const int views = o.simulate * (cut + 1) / o.edge_cuts - o.simulate * cut / o.edge_cuts;
    const algorithms::Line2 line = algorithms::RandomCut(lo, hi, rng);
    const std::vector<MapTree> map = Searched(algorithms::KeepBehind(forest, line), o);
    if (map.size() < 3) continue;
    if (runner) {
      runner->UseMap(map);
    } else {
      runner.emplace(map, o, false);
    }
    const unsigned seed = o.maps.seed * 7919u + static_cast<unsigned>(cut);
    const auto poses =
        SampleViewPoses(simulator, views, margin, seed, o.range, [&](const Eigen::Vector3d& p) {
          return std::abs(line.SignedDistance(p.head<2>())) <= o.edge_band;
        });
    for (size_t i = 0; i < poses.size(); ++i) {
      algorithms::ViewOptions view = ViewModel(o, o.range);
      view.seed = seed * 100003u + static_cast<unsigned>(i);
      const algorithms::SimulatedView v =
          simulator.Simulate(poses[i].head<2>(), poses[i].z(), view);
      runner->Run(v.trees, v.map_from_sensor);
      LabProgress(err, "bench-reloc", ++done, o.simulate, 50);
    }
  }
  if (!runner) throw CommandError("no cut left 3 trees on its side");
  return runner->Report(forest.size());
}

// A view from one plot's centre relocalized in its neighbour's map, each pair its own map.
nlohmann::ordered_json RunOverlap(const std::vector<MapTree>& forest, const BenchOptions& o,
                                  std::ostream& err) {
  const algorithms::ViewSimulator simulator(forest);
  const Eigen::Vector2d lo = simulator.grid().min_corner(), hi = simulator.grid().max_corner();
  std::mt19937 rng(o.maps.seed);
  std::optional<Runner> runner;
  for (int pair = 0; pair < o.simulate; ++pair) {
    const auto plots =
        algorithms::NeighbourPlots(lo, hi, o.plot_radius, o.plot_apart[0], o.plot_apart[1], rng);
    if (!plots) throw CommandError("the map is too small for two plots of this radius");
    const std::vector<MapTree> map =
        Searched(algorithms::CircularPlot(forest, plots->second, o.plot_radius), o);
    if (map.size() < 3) continue;
    if (runner) {
      runner->UseMap(map);
    } else {
      runner.emplace(map, o, false);
    }
    algorithms::ViewOptions view = ViewModel(o, o.plot_radius);
    view.seed = o.maps.seed * 100003u + static_cast<unsigned>(pair);
    const double yaw = std::uniform_real_distribution<double>(-M_PI, M_PI)(rng);
    const algorithms::SimulatedView v = simulator.Simulate(plots->first, yaw, view);
    runner->Run(v.trees, v.map_from_sensor);
    LabProgress(err, "bench-reloc", pair + 1, o.simulate, 50);
  }
  if (!runner) throw CommandError("no plot held 3 trees");
  return runner->Report(forest.size());
}

}  // namespace

void AddCoverageCaseOptions(CLI::App* cmd, BenchOptions& o) {
  cmd->add_flag("--edge", o.edge,
                "Cut the map (--map) by lines of random direction, each side kept its own map; "
                "views (--simulate N in all) in the whole forest within --edge-band of the cut");
  cmd->add_option("--edge-band", o.edge_band, "Views within this distance of the cut (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--edge-cuts", o.edge_cuts, "Cuts (maps) the --edge views are spread over")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_flag("--overlap", o.overlap,
                "Neighbouring circular plots of the map (--map), each its own map: a view from "
                "one plot's centre relocalized in the other's map (--simulate N pairs)");
  cmd->add_option("--plot-radius", o.plot_radius, "Radius of the --overlap plots (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--plot-apart", o.plot_apart, "MIN,MAX distance of the plots' centres (m)")
      ->delimiter(',')
      ->expected(2)
      ->capture_default_str();
  cmd->add_option("--answerable-trees", o.answerable_trees,
                  "Mapped trees in sight (within 20 m) that make a view answerable")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--max-density", o.max_density,
                  "Only views whose map holds fewer trees per m^2 than this within --range")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--miss", o.miss_rate, "Simulated views: share of visible trees missed")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--far-miss", o.far_miss_rate,
                  "... rising linearly to this share at --range (default: constant)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--noise-per-m", o.noise_per_metre,
                  "Simulated views: position noise added per metre of range to the 5 cm (m/m)")
      ->check(CLI::NonNegativeNumber);
}

algorithms::ViewOptions ViewModel(const BenchOptions& o, double range) {
  algorithms::ViewOptions view;  // occlusion, 20% false stems, 5 cm noise
  view.range = range;
  view.miss_rate = o.miss_rate;
  view.far_miss_rate = o.far_miss_rate;
  view.noise_per_metre = o.noise_per_metre;
  return view;
}

std::vector<Eigen::Vector3d> SampleViewPoses(
    const algorithms::ViewSimulator& simulator, int count, double margin, unsigned seed,
    double range, const std::function<bool(const Eigen::Vector3d&)>& keep) {
  constexpr int kBatches = 50;
  std::vector<Eigen::Vector3d> kept;
  for (int batch = 0; batch < kBatches && static_cast<int>(kept.size()) < count; ++batch) {
    for (const Eigen::Vector3d& p :
         simulator.SamplePoses(4 * count, margin, seed + 65537u * batch, 8, range)) {
      if (static_cast<int>(kept.size()) < count && keep(p)) kept.push_back(p);
    }
  }
  return kept;
}

nlohmann::ordered_json RunCoverageCase(const std::vector<MapTree>& forest, const BenchOptions& o,
                                       std::ostream& err) {
  return o.edge ? RunEdge(forest, o, err) : RunOverlap(forest, o, err);
}

}  // namespace forestmap::client
