// GroundOptions::Check and the ground model's height lookup (ground_model.h); the segmentation
// that builds the model is in ground_model.cc.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "algorithms/detection/ground_model.h"

namespace forestmap::algorithms {

void GroundOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("GroundOptions: ") + what);
  };
  require(cell_size > 0, "cell_size must be > 0");
  require(candidate_height > 0, "candidate_height must be > 0");
  require(subcell_size > 0 && subcell_size <= cell_size, "need 0 < subcell_size <= cell_size");
  require(max_subcell_extent > 0, "max_subcell_extent must be > 0");
  require(min_cell_points >= 1, "min_cell_points must be >= 1");
  require(min_ground_share >= 0 && min_ground_share <= 1, "min_ground_share must be in [0, 1]");
  require(max_step >= 0 && max_slope >= 0, "max_step and max_slope must be >= 0");
  require(min_ground_cells >= 1, "min_ground_cells must be >= 1");
  require(fill_radius >= 1, "fill_radius must be >= 1");
  require(max_grid_cells >= 1, "max_grid_cells must be >= 1");
}

GroundModel::GroundModel(double min_x, double min_y, double cell, int nx, int ny,
                         std::vector<float> heights)
    : min_x_(min_x), min_y_(min_y), cell_(cell), nx_(nx), ny_(ny), heights_(std::move(heights)) {}

double GroundModel::Height(double x, double y) const {
  if (heights_.empty()) return kUnknown;
  const double fx = (x - min_x_) / cell_ - 0.5, fy = (y - min_y_) / cell_ - 0.5;
  const int ix = static_cast<int>(std::floor(fx)), iy = static_cast<int>(std::floor(fy));
  const double tx = fx - ix, ty = fy - iy;
  // Inside the grid with all four corners known (most points): plain bilinear interpolation.
  if (ix >= 0 && iy >= 0 && ix + 1 < nx_ && iy + 1 < ny_) {
    const float* row = heights_.data() + static_cast<size_t>(iy) * nx_ + ix;
    const float h00 = row[0], h10 = row[1], h01 = row[nx_], h11 = row[nx_ + 1];
    if (!std::isnan(h00 + h10 + h01 + h11)) {
      return (1 - ty) * ((1 - tx) * h00 + tx * h10) + ty * ((1 - tx) * h01 + tx * h11);
    }
  }
  double sum = 0, weight = 0;
  for (int dy = 0; dy <= 1; ++dy) {
    for (int dx = 0; dx <= 1; ++dx) {
      const int jx = ix + dx, jy = iy + dy;
      if (jx < 0 || jy < 0 || jx >= nx_ || jy >= ny_) continue;
      const float h = heights_[static_cast<size_t>(jy) * nx_ + jx];
      if (std::isnan(h)) continue;
      const double w = (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty) + 1e-9;
      sum += w * h;
      weight += w;
    }
  }
  return weight > 0 ? sum / weight : kUnknown;
}

}  // namespace forestmap::algorithms
