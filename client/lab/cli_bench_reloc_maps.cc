#include "client/lab/cli_bench_reloc_maps.h"

#include <cmath>
#include <ostream>

#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/stand_cases.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

using algorithms::MapTree;

std::vector<MapTree> Generated(const BenchMapOptions& o, unsigned seed, std::ostream& err) {
  const auto like = ToMapTrees(ReadMapTreesCsv(o.like_path));
  const algorithms::StemMapStatistics stats = algorithms::EstimateStemMapStatistics(like);
  algorithms::ForestOptions forest;
  forest.width = forest.height = std::sqrt(o.generate / stats.density);
  forest.seed = seed;
  std::vector<MapTree> map = algorithms::GenerateForest(stats, forest);
  err << "bench-reloc: generated " << map.size() << " trees on " << static_cast<int>(forest.width)
      << " m x " << static_cast<int>(forest.height) << " m like " << o.like_path << "\n";
  return map;
}

std::vector<MapTree> Mosaic(const BenchMapOptions& o, unsigned seed, std::ostream& err) {
  std::vector<std::vector<MapTree>> stands;
  for (const std::string& path : o.mosaic) stands.push_back(ToMapTrees(ReadMapTreesCsv(path)));
  algorithms::MosaicOptions mosaic;
  mosaic.trees = o.mosaic_trees;
  mosaic.seed = seed;
  std::vector<MapTree> map = algorithms::TileMosaic(stands, mosaic);
  err << "bench-reloc: mosaic of " << map.size() << " trees from " << stands.size()
      << " stem maps (tiles of " << mosaic.tile << " m, random angles, " << mosaic.jitter
      << " m jitter, " << 100 * mosaic.thinning << "% thinned)\n";
  return map;
}

std::vector<MapTree> Plantation(const BenchMapOptions& o, unsigned seed, std::ostream& err) {
  algorithms::PlantationOptions p;
  p.spacing_x = o.plantation[0];
  p.spacing_y = o.plantation[1];
  p.planting_error = o.plantation[2];
  p.mortality = o.plantation[3];
  p.width = p.height = o.plantation_size;
  p.seed = seed;
  std::vector<MapTree> map = algorithms::GeneratePlantation(p);
  err << "bench-reloc: plantation of " << map.size() << " trees (" << p.spacing_x << " m x "
      << p.spacing_y << " m, " << p.planting_error << " m planting error, " << 100 * p.mortality
      << "% mortality, seed " << seed << ")\n";
  return map;
}

// The map of the chosen kind with this seed.
std::vector<MapTree> Make(const BenchMapOptions& o, unsigned seed, std::ostream& err) {
  if (o.generate > 0) return Generated(o, seed, err);
  if (!o.mosaic.empty()) return Mosaic(o, seed, err);
  if (!o.plantation.empty()) return Plantation(o, seed, err);
  return ToMapTrees(ReadMapTreesCsv(o.map_path));
}

}  // namespace

void AddBenchMapOptions(CLI::App* cmd, BenchMapOptions& o) {
  cmd->add_option("--map", o.map_path, "Map CSV (id,x,y[,z,dbh])")->check(CLI::ExistingFile);
  cmd->add_option("--generate", o.generate,
                  "Generate a map of N trees with the spatial statistics of --like")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--like", o.like_path, "Stem map whose statistics --generate copies")
      ->check(CLI::ExistingFile);
  cmd->add_option("--mosaic", o.mosaic,
                  "A district tiled from these stem maps (tiles of 315 m, each a random one of "
                  "them, rotated at random, trees jittered by 1 m, 15% thinned; seeded)")
      ->delimiter(',')
      ->check(CLI::ExistingFile);
  cmd->add_option("--mosaic-trees", o.mosaic_trees, "Trees of the --mosaic map")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--plantation", o.plantation,
                  "SX,SY,ERROR,MORTALITY: a plantation, SX x SY m spacing, planting error ERROR m "
                  "(sd per axis), MORTALITY share of dead trees (seeded)")
      ->delimiter(',')
      ->expected(4);
  cmd->add_option("--plantation-size", o.plantation_size, "Side of the square plantation (m)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--foreign-map", o.foreign_map_path,
                  "Relocalize the views in this other map: every LOCALIZED answer is wrong")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--no-dbh", o.no_dbh,
                "Remove the DBH of the map searched (a survey of positions only); the views still "
                "see and measure the trunks");
  cmd->add_flag("--foreign", o.foreign_seed,
                "Relocalize the views in a map of the same kind with another seed (--plantation, "
                "--generate, --mosaic): every LOCALIZED answer is wrong");
}

void CheckBenchMapOptions(const BenchMapOptions& o, bool simulate) {
  const int kinds =
      (o.generate > 0) + !o.mosaic.empty() + !o.plantation.empty() + !o.map_path.empty();
  if (kinds != 1) {
    throw CLI::ValidationError("--map",
                               "give exactly one of --map, --generate, --mosaic, --plantation");
  }
  if (o.generate > 0 && o.like_path.empty()) {
    throw CLI::ValidationError("--generate", "needs --like STEMMAP.csv");
  }
  if ((o.generate > 0 || !o.mosaic.empty() || !o.plantation.empty()) && !simulate) {
    throw CLI::ValidationError("--simulate", "generated maps need --simulate N");
  }
  if (o.foreign_seed && !o.map_path.empty()) {
    throw CLI::ValidationError("--foreign", "a stem map has no other seed; use --foreign-map");
  }
  if (!o.foreign_map_path.empty() && !simulate) {
    throw CLI::ValidationError("--foreign-map", "needs --simulate N");
  }
}

BenchMaps LoadBenchMaps(const BenchMapOptions& o, std::ostream& err) {
  BenchMaps maps;
  maps.views = Make(o, o.seed, err);
  if (maps.views.size() < 3) throw CommandError("the map has fewer than 3 trees");
  if (!o.foreign_map_path.empty()) {
    maps.index = ToMapTrees(ReadMapTreesCsv(o.foreign_map_path));
    maps.foreign = true;
  } else if (o.foreign_seed) {
    constexpr unsigned kOtherSeed = 7919;  // any other seed: another stand of the same design
    maps.index = Make(o, o.seed + kOtherSeed, err);
    maps.foreign = true;
  } else {
    maps.index = maps.views;
  }
  if (maps.index.size() < 3) throw CommandError("the map searched has fewer than 3 trees");
  if (o.no_dbh) {
    for (MapTree& t : maps.index) t.dbh = algorithms::kUnknown;
  }
  return maps;
}

}  // namespace forestmap::client
