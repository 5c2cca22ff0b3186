#pragma once
// The maps `forestmap-lab bench-reloc` measures against: a stem map, a generated forest, a mosaic
// of stem maps, a plantation; and the map the views are relocalized in (the same one, or a
// foreign one where every LOCALIZED answer is wrong).

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::client {

struct BenchMapOptions {
  std::string map_path;             // --map
  int64_t generate = 0;             // --generate N trees ...
  std::string like_path;            // ... like this stem map
  std::vector<std::string> mosaic;  // --mosaic A.csv,B.csv,...
  size_t mosaic_trees = 1000000;    // --mosaic-trees
  std::vector<double> plantation;   // --plantation SX,SY,ERROR,MORTALITY (m, m, m, share)
  double plantation_size = 200;     // m, --plantation-size (square)
  std::string foreign_map_path;     // --foreign-map: relocalize the views in this map
  bool foreign_seed = false;        // --foreign: ... in the same kind of map, another seed
  bool no_dbh = false;              // --no-dbh: the maps without DBH (positions only)
  unsigned seed = 1;                // --seed
};

struct BenchMaps {
  std::vector<algorithms::MapTree> views;  // the map the sensor is in (truth)
  std::vector<algorithms::MapTree> index;  // the map it is relocalized in
  bool foreign = false;                    // index is another forest: any LOCALIZED is wrong
};

void AddBenchMapOptions(CLI::App* cmd, BenchMapOptions& options);
// Throws CLI::ValidationError for a combination that names no map.
void CheckBenchMapOptions(const BenchMapOptions& options, bool simulate);
BenchMaps LoadBenchMaps(const BenchMapOptions& options, std::ostream& err);

}  // namespace forestmap::client
