#include "algorithms/detection/ground_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
constexpr int kMaxSub = 32;  // sub-cells per pillar side at most

struct Grid {
  double min_x = 0, min_y = 0, cell = 1;
  int nx = 0, ny = 0;
  int Cell(float x, float y) const {
    const int ix = std::clamp(static_cast<int>((x - min_x) / cell), 0, nx - 1);
    const int iy = std::clamp(static_cast<int>((y - min_y) / cell), 0, ny - 1);
    return iy * nx + ix;
  }
  Eigen::Vector2d Centre(int ix, int iy) const {
    return {min_x + (ix + 0.5) * cell, min_y + (iy + 0.5) * cell};
  }
};

struct Sample {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  bool valid = false;
};

Grid MakeGrid(std::span<const Eigen::Vector3f> points, const GroundOptions& options) {
  float min_x = std::numeric_limits<float>::max(), min_y = min_x;
  float max_x = std::numeric_limits<float>::lowest(), max_y = max_x;
  for (const Eigen::Vector3f& p : points) {
    min_x = std::min(min_x, p.x());
    min_y = std::min(min_y, p.y());
    max_x = std::max(max_x, p.x());
    max_y = std::max(max_y, p.y());
  }
  Grid grid;
  grid.min_x = min_x;
  grid.min_y = min_y;
  grid.cell = options.cell_size;
  for (;;) {
    grid.nx = static_cast<int>((max_x - min_x) / grid.cell) + 1;
    grid.ny = static_cast<int>((max_y - min_y) / grid.cell) + 1;
    if (static_cast<size_t>(grid.nx) * grid.ny <= options.max_grid_cells) break;
    grid.cell *= 1.5;
  }
  return grid;
}

// Ground sample of one pillar: the mean of its candidates that pass the vertical-structure test.
Sample PillarSample(std::span<const Eigen::Vector3f> points, std::span<const uint32_t> members,
                    const Grid& grid, int ix, int iy, const GroundOptions& options) {
  float lowest = std::numeric_limits<float>::max();
  for (uint32_t i : members) lowest = std::min(lowest, points[i].z());
  const int ns =
      std::clamp(static_cast<int>(std::ceil(grid.cell / options.subcell_size)), 1, kMaxSub);
  const double sub = grid.cell / ns;
  const double x0 = grid.min_x + ix * grid.cell, y0 = grid.min_y + iy * grid.cell;
  std::array<float, kMaxSub * kMaxSub> sub_min, sub_max;
  std::array<uint8_t, kMaxSub * kMaxSub> used{};
  const float limit = lowest + static_cast<float>(options.candidate_height);
  auto sub_of = [&](const Eigen::Vector3f& p) {
    const int sx = std::clamp(static_cast<int>((p.x() - x0) / sub), 0, ns - 1);
    const int sy = std::clamp(static_cast<int>((p.y() - y0) / sub), 0, ns - 1);
    return sy * ns + sx;
  };
  for (uint32_t i : members) {
    const Eigen::Vector3f& p = points[i];
    if (p.z() > limit) continue;
    const int s = sub_of(p);
    if (!used[s]) {
      used[s] = 1;
      sub_min[s] = sub_max[s] = p.z();
    } else {
      sub_min[s] = std::min(sub_min[s], p.z());
      sub_max[s] = std::max(sub_max[s], p.z());
    }
  }
  Sample sample;
  int count = 0, candidates = 0;
  for (uint32_t i : members) {
    const Eigen::Vector3f& p = points[i];
    if (p.z() > limit) continue;
    ++candidates;
    const int s = sub_of(p);
    if (sub_max[s] - sub_min[s] > options.max_subcell_extent) continue;
    sample.p += p.cast<double>();
    ++count;
  }
  // Mostly vertical structure (a stem ring whose edge sub-cells happen to look flat) is no
  // ground either.
  if (count >= options.min_cell_points && count >= options.min_ground_share * candidates) {
    sample.p /= count;
    sample.valid = true;
  }
  return sample;
}

// Drops pillars whose ground lies too high above anything in a neighbouring pillar (ground is the
// lowest surface): a shrub top, a crown's underside or a stem where the real ground was hidden,
// as under a drone whose narrow field of view sees ground only far away.
int RejectHighSamples(std::vector<Sample>& samples, const std::vector<Eigen::Vector3f>& lowest,
                      const Grid& grid, const GroundOptions& options) {
  constexpr int kReach = 4;  // pillars
  std::vector<uint8_t> reject(samples.size(), 0);
  for (int iy = 0; iy < grid.ny; ++iy) {
    for (int ix = 0; ix < grid.nx; ++ix) {
      const Sample& s = samples[iy * grid.nx + ix];
      if (!s.valid) continue;
      for (int dy = -kReach; dy <= kReach && !reject[iy * grid.nx + ix]; ++dy) {
        for (int dx = -kReach; dx <= kReach; ++dx) {
          const int jx = ix + dx, jy = iy + dy;
          if ((dx == 0 && dy == 0) || jx < 0 || jy < 0 || jx >= grid.nx || jy >= grid.ny) continue;
          const Eigen::Vector3f& n = lowest[jy * grid.nx + jx];
          if (!std::isfinite(n.z())) continue;
          const double dist = (s.p.head<2>() - n.head<2>().cast<double>()).norm();
          if (s.p.z() - n.z() > options.max_step + options.max_slope * dist) {
            reject[iy * grid.nx + ix] = 1;
            break;
          }
        }
      }
    }
  }
  int kept = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    if (reject[i]) samples[i].valid = false;
    kept += samples[i].valid;
  }
  return kept;
}

// Drops the samples that lie above a beam from the origin which passed over them to a farther
// return (sensor_at_origin): the ground there is below that beam, unseen. Per azimuth bin and
// per distance band, the lowest elevation (its tangent) of the returns beyond each distance.
int RejectSamplesAboveFreeBeams(std::vector<Sample>& samples,
                                std::span<const Eigen::Vector3f> points, const Grid& grid) {
  const double cell = grid.cell;
  constexpr int kBins = 720;      // azimuth, 0.5 deg
  constexpr int kMaxBands = 256;  // distance bands
  // m: a sample higher than this above a beam that passed over it is no ground. Not negative:
  // ground grazed by a beam sloping down with it lies on that beam, within the range noise.
  constexpr double kMargin = 0.0;
  // The farthest corner of the grid bounds every point's distance.
  double max_d = 0;
  for (double x : {grid.min_x, grid.min_x + grid.nx * cell}) {
    for (double y : {grid.min_y, grid.min_y + grid.ny * cell}) {
      max_d = std::max(max_d, std::hypot(x, y));
    }
  }
  const double band = std::max(cell, max_d / (kMaxBands - 1));
  const int bands = static_cast<int>(max_d / band) + 2;
  // lowest[bin * bands + k]: min tan(elevation) of the returns at distance band k, then of all
  // returns beyond band k (a suffix minimum).
  std::vector<float> lowest(static_cast<size_t>(kBins) * bands,
                            std::numeric_limits<float>::infinity());
  // Azimuth bins by the "diamond angle" in [0, 4) (monotonic in the azimuth, no atan2 per
  // point; bins 0.4-0.7 deg wide).
  auto bin_of = [](double x, double y) {
    const double l1 = std::abs(x) + std::abs(y);
    const double a = y >= 0 ? (x >= 0 ? y / l1 : 1 - x / l1) : (x < 0 ? 2 - y / l1 : 3 + x / l1);
    return std::clamp(static_cast<int>(a * (kBins / 4)), 0, kBins - 1);
  };
  for (const Eigen::Vector3f& p : points) {
    const float d = p.head<2>().norm();
    if (d < 1e-3f) continue;
    float& t =
        lowest[static_cast<size_t>(bin_of(p.x(), p.y())) * bands + static_cast<int>(d / band)];
    t = std::min(t, p.z() / d);
  }
  for (int b = 0; b < kBins; ++b) {
    float* row = lowest.data() + static_cast<size_t>(b) * bands;
    for (int k = bands - 2; k >= 0; --k) row[k] = std::min(row[k], row[k + 1]);
  }
  int kept = 0;
  for (Sample& s : samples) {
    if (!s.valid) continue;
    const double d = s.p.head<2>().norm();
    // Beams that reached beyond the sample's pillar (one pillar and one band further on).
    const int k = static_cast<int>((d + cell) / band) + 1;
    if (k < bands) {
      const float t = lowest[static_cast<size_t>(bin_of(s.p.x(), s.p.y())) * bands + k];
      if (s.p.z() > d * t + kMargin) s.valid = false;
    }
    kept += s.valid;
  }
  return kept;
}

// The least-squares plane z = a + b x + c y through all ground samples; false when they do not
// span one.
bool GlobalPlane(const std::vector<Sample>& samples, Eigen::Vector3d* plane) {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  int n = 0;
  for (const Sample& s : samples) {
    if (!s.valid) continue;
    const Eigen::Vector3d row(1, s.p.x(), s.p.y());
    ata += row * row.transpose();
    atb += s.p.z() * row;
    ++n;
  }
  if (n < 3) return false;
  Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
  if (ldlt.info() != Eigen::Success || ldlt.rcond() < 1e-9) return false;
  *plane = ldlt.solve(atb);
  return plane->allFinite();
}

// Sums of the ground samples over pillar rectangles in O(1) (summed-area tables), for the
// window searches of CentreHeight. Coordinates relative to the grid corner keep them exact.
class SampleSums {
 public:
  SampleSums(const std::vector<Sample>& samples, const Grid& grid)
      : nx_(grid.nx), ny_(grid.ny), table_(static_cast<size_t>(nx_ + 1) * (ny_ + 1)) {
    for (int iy = 0; iy < ny_; ++iy) {
      for (int ix = 0; ix < nx_; ++ix) {
        Sums own{};
        const Sample& s = samples[static_cast<size_t>(iy) * nx_ + ix];
        if (s.valid) {
          const double x = s.p.x() - grid.min_x, y = s.p.y() - grid.min_y, z = s.p.z();
          own = {1, x, y, z, x * x, x * y, y * y, x * z, y * z};
        }
        Sums& out = At(ix + 1, iy + 1);
        for (int k = 0; k < 9; ++k) {
          out[k] = own[k] + At(ix, iy + 1)[k] + At(ix + 1, iy)[k] - At(ix, iy)[k];
        }
      }
    }
  }
  using Sums = std::array<double, 9>;  // n, x, y, z, xx, xy, yy, xz, yz
  // Sums over pillars [x0, x1] x [y0, y1] (clamped to the grid).
  Sums Box(int x0, int y0, int x1, int y1) const {
    x0 = std::max(x0, 0), y0 = std::max(y0, 0);
    x1 = std::min(x1, nx_ - 1) + 1, y1 = std::min(y1, ny_ - 1) + 1;
    Sums out;
    for (int k = 0; k < 9; ++k) {
      out[k] = At(x1, y1)[k] - At(x0, y1)[k] - At(x1, y0)[k] + At(x0, y0)[k];
    }
    return out;
  }

 private:
  Sums& At(int ix, int iy) { return table_[static_cast<size_t>(iy) * (nx_ + 1) + ix]; }
  const Sums& At(int ix, int iy) const { return table_[static_cast<size_t>(iy) * (nx_ + 1) + ix]; }
  int nx_, ny_;
  std::vector<Sums> table_;
};

// Height at a pillar centre from the smallest window around it that holds enough ground samples
// (Holmgren et al. sec. 2.5, there by inverse distance weighting): a least-squares plane through
// them when they span one (slopes, and extrapolation under the drone where a narrow field of
// view sees no ground), else their mean height.
float CentreHeight(const SampleSums& sums, const Grid& grid, int ix, int iy, int fill_radius) {
  constexpr int kPlaneSamples = 6;
  const double cx = (ix + 0.5) * grid.cell, cy = (iy + 0.5) * grid.cell;
  for (int w = 1; w <= fill_radius; ++w) {
    const SampleSums::Sums s = sums.Box(ix - w, iy - w, ix + w, iy + w);
    const double n = s[0];
    if (n == 0 || (n < kPlaneSamples && w < fill_radius)) continue;
    if (n >= 3) {
      // Normal equations of z = a + b (x - cx) + c (y - cy).
      const double sx = s[1] - n * cx, sy = s[2] - n * cy;
      const double sxx = s[4] - 2 * cx * s[1] + n * cx * cx;
      const double sxy = s[5] - cx * s[2] - cy * s[1] + n * cx * cy;
      const double syy = s[6] - 2 * cy * s[2] + n * cy * cy;
      const double sxz = s[7] - cx * s[3], syz = s[8] - cy * s[3];
      Eigen::Matrix3d ata;
      ata << n, sx, sy, sx, sxx, sxy, sy, sxy, syy;
      const Eigen::Vector3d atb(s[3], sxz, syz);
      // The samples span a plane unless they are (nearly) collinear: the centred 2x2 scatter
      // of their x, y must not be singular (closed form; an eigen solver per pillar is costly).
      const double vxx = sxx - sx * sx / n, vxy = sxy - sx * sy / n, vyy = syy - sy * sy / n;
      const double trace = vxx + vyy;
      if (vxx * vyy - vxy * vxy > 1e-6 * trace * trace) {
        const Eigen::Vector3d plane = ata.inverse() * atb;  // 3x3: closed-form inverse
        if (plane.tail<2>().norm() < 2.0) return static_cast<float>(plane(0));
      }
    }
    return static_cast<float>(s[3] / n);
  }
  return kNaNf;
}

}  // namespace

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

GroundSegmentation SegmentGround(std::span<const Eigen::Vector3f> points,
                                 const GroundOptions& options) {
  options.Check();
  GroundSegmentation result;
  result.height.assign(points.size(), kNaNf);
  result.is_ground.assign(points.size(), 0);
  if (points.empty()) return result;
  const Grid grid = MakeGrid(points, options);
  const size_t cells = static_cast<size_t>(grid.nx) * grid.ny;

  // Counting sort of the points by pillar.
  std::vector<uint32_t> start(cells + 1, 0);
  std::vector<uint32_t> cell_of(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    cell_of[i] = grid.Cell(points[i].x(), points[i].y());
    ++start[cell_of[i] + 1];
  }
  for (size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
  std::vector<uint32_t> order(points.size());
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < points.size(); ++i) order[fill[cell_of[i]]++] = i;
  }

  std::vector<Sample> samples(cells);
  for (int iy = 0; iy < grid.ny; ++iy) {
    for (int ix = 0; ix < grid.nx; ++ix) {
      const size_t c = static_cast<size_t>(iy) * grid.nx + ix;
      if (start[c + 1] - start[c] < static_cast<uint32_t>(options.min_cell_points)) continue;
      const std::span<const uint32_t> members(order.data() + start[c], start[c + 1] - start[c]);
      samples[c] = PillarSample(points, members, grid, ix, iy, options);
    }
  }
  std::vector<Eigen::Vector3f> lowest(
      cells, Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity()));
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].z() < lowest[cell_of[i]].z()) lowest[cell_of[i]] = points[i];
  }
  result.ground_cells = RejectHighSamples(samples, lowest, grid, options);
  if (options.sensor_at_origin) {
    result.ground_cells = RejectSamplesAboveFreeBeams(samples, points, grid);
  }
  result.ground_known = result.ground_cells >= options.min_ground_cells;

  if (!result.ground_known) {
    float lowest_z = std::numeric_limits<float>::max();
    for (const Eigen::Vector3f& p : points) lowest_z = std::min(lowest_z, p.z());
    result.reference_z = lowest_z;
    for (size_t i = 0; i < points.size(); ++i) result.height[i] = points[i].z() - lowest_z;
    return result;
  }

  // Heights at the centres of occupied pillars and their neighbours (bilinear interpolation
  // reaches one pillar out).
  std::vector<float> heights(cells, kNaNf);
  const SampleSums sums(samples, grid);
  Eigen::Vector3d plane;
  const bool with_plane = options.sensor_at_origin && GlobalPlane(samples, &plane);
  for (int iy = 0; iy < grid.ny; ++iy) {
    for (int ix = 0; ix < grid.nx; ++ix) {
      bool needed = false;
      for (int jy = std::max(0, iy - 1); jy <= std::min(grid.ny - 1, iy + 1) && !needed; ++jy) {
        for (int jx = std::max(0, ix - 1); jx <= std::min(grid.nx - 1, ix + 1); ++jx) {
          const size_t c = static_cast<size_t>(jy) * grid.nx + jx;
          if (start[c + 1] > start[c]) {
            needed = true;
            break;
          }
        }
      }
      if (needed) {
        float& h = heights[static_cast<size_t>(iy) * grid.nx + ix];
        h = CentreHeight(sums, grid, ix, iy, options.fill_radius);
        if (std::isnan(h) && with_plane) {
          const Eigen::Vector2d c = grid.Centre(ix, iy);
          h = static_cast<float>(plane(0) + plane(1) * c.x() + plane(2) * c.y());
        }
      }
    }
  }
  result.model =
      GroundModel(grid.min_x, grid.min_y, grid.cell, grid.nx, grid.ny, std::move(heights));
  for (size_t i = 0; i < points.size(); ++i) {
    const double ground = result.model.Height(points[i].x(), points[i].y());
    if (std::isnan(ground)) continue;
    const float h = static_cast<float>(points[i].z() - ground);
    result.height[i] = h;
    if (h < options.label_height) {
      result.is_ground[i] = 1;
      ++result.ground_points;
    }
  }
  return result;
}

}  // namespace forestmap::algorithms
