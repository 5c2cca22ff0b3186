#include "algorithms/simulation/stand_cases.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "algorithms/core/check.h"

namespace forestmap::algorithms {
namespace {

// The stand's trees relative to the centre of its bounding box; the box's half diagonal.
std::vector<MapTree> Centred(const std::vector<MapTree>& stand, double* half_diagonal) {
  Eigen::Vector2d lo = stand.front().position.head<2>(), hi = lo;
  for (const MapTree& t : stand) {
    lo = lo.cwiseMin(t.position.head<2>());
    hi = hi.cwiseMax(t.position.head<2>());
  }
  const Eigen::Vector2d centre = (lo + hi) / 2;
  std::vector<MapTree> out = stand;
  for (MapTree& t : out) t.position.head<2>() -= centre;
  *half_diagonal = (hi - lo).norm() / 2;
  return out;
}

}  // namespace

void PlantationOptions::Check() const {
  Require(spacing_x > 0 && spacing_y > 0, "PlantationOptions: spacing must be > 0");
  Require(planting_error >= 0, "PlantationOptions: planting_error must be >= 0");
  Require(mortality >= 0 && mortality < 1, "PlantationOptions: mortality must be in [0, 1)");
  Require(width >= spacing_x && height >= spacing_y,
          "PlantationOptions: width/height must hold at least one spacing");
  Require(dbh_mean > 0 && dbh_log_sd >= 0, "PlantationOptions: dbh_mean > 0, dbh_log_sd >= 0");
}

std::vector<MapTree> GeneratePlantation(const PlantationOptions& options) {
  options.Check();
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> error(0, options.planting_error);
  std::normal_distribution<double> log_dbh(std::log(options.dbh_mean), options.dbh_log_sd);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::vector<MapTree> trees;
  const int columns = static_cast<int>(options.width / options.spacing_x);
  const int rows = static_cast<int>(options.height / options.spacing_y);
  for (int i = 0; i < columns; ++i) {
    for (int j = 0; j < rows; ++j) {
      const double dx = error(rng), dy = error(rng), dbh = log_dbh(rng);
      if (uniform(rng) < options.mortality) continue;
      MapTree t;
      t.id = static_cast<int64_t>(trees.size());
      t.position = {(i + 0.5) * options.spacing_x + dx, (j + 0.5) * options.spacing_y + dy,
                    kUnknown};
      t.dbh = std::clamp(dbh, 0.02, 2.0);
      trees.push_back(t);
    }
  }
  return trees;
}

void MosaicOptions::Check() const {
  Require(trees > 0, "MosaicOptions: trees must be > 0");
  Require(tile > 0, "MosaicOptions: tile must be > 0");
  Require(jitter >= 0, "MosaicOptions: jitter must be >= 0");
  Require(thinning >= 0 && thinning < 1, "MosaicOptions: thinning must be in [0, 1)");
}

std::vector<MapTree> TileMosaic(const std::vector<std::vector<MapTree>>& stands,
                                const MosaicOptions& options) {
  options.Check();
  Require(!stands.empty(), "TileMosaic: no stands");
  std::vector<std::vector<MapTree>> centred;
  double mean_trees = 0;
  for (size_t s = 0; s < stands.size(); ++s) {
    Require(!stands[s].empty(), "TileMosaic: stand " + std::to_string(s) + " is empty");
    double half_diagonal = 0;
    centred.push_back(Centred(stands[s], &half_diagonal));
    Require(2 * half_diagonal <= options.tile, "TileMosaic: stand " + std::to_string(s) +
                                                   " is wider than a tile of " +
                                                   std::to_string(options.tile) + " m");
    mean_trees += stands[s].size() * (1 - options.thinning) / stands.size();
  }
  // A square grid: columns from the expected number of tiles.
  const int columns =
      std::max(1, static_cast<int>(std::ceil(std::sqrt(options.trees / mean_trees))));
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<size_t> pick(0, stands.size() - 1);
  std::uniform_real_distribution<double> angle(-M_PI, M_PI), uniform(0, 1);
  std::normal_distribution<double> jitter(0, options.jitter);
  std::vector<MapTree> out;
  for (int tile = 0; out.size() < options.trees; ++tile) {
    const Eigen::Vector2d centre((tile % columns + 0.5) * options.tile,
                                 (tile / columns + 0.5) * options.tile);
    const Eigen::Rotation2Dd rotation(angle(rng));
    for (const MapTree& t : centred[pick(rng)]) {
      const Eigen::Vector2d offset(jitter(rng), jitter(rng));
      if (uniform(rng) < options.thinning) continue;
      MapTree moved = t;
      moved.id = static_cast<int64_t>(out.size());
      moved.position.head<2>() = centre + rotation * t.position.head<2>() + offset;
      out.push_back(moved);
    }
  }
  return out;
}

}  // namespace forestmap::algorithms
