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

namespace {

// The points sorted by pillar (a counting sort): pillar c holds order[start[c] .. start[c + 1]).
struct PillarIndex {
  std::vector<uint32_t> start;    // per pillar, plus one past the end
  std::vector<uint32_t> cell_of;  // per point: its pillar
  std::vector<uint32_t> order;    // point indices, pillar by pillar
  bool Occupied(size_t c) const { return start[c + 1] > start[c]; }
};

PillarIndex SortByPillar(std::span<const Eigen::Vector3f> points, const Grid& grid) {
  const size_t cells = static_cast<size_t>(grid.nx) * grid.ny;
  PillarIndex index{std::vector<uint32_t>(cells + 1, 0), std::vector<uint32_t>(points.size()),
                    std::vector<uint32_t>(points.size())};
  for (size_t i = 0; i < points.size(); ++i) {
    index.cell_of[i] = grid.Cell(points[i].x(), points[i].y());
    ++index.start[index.cell_of[i] + 1];
  }
  for (size_t c = 0; c < cells; ++c) index.start[c + 1] += index.start[c];
  std::vector<uint32_t> fill(index.start.begin(), index.start.end() - 1);
  for (size_t i = 0; i < points.size(); ++i) index.order[fill[index.cell_of[i]]++] = i;
  return index;
}

// One ground sample per pillar of at least min_cell_points points, then the samples rejected
// above their neighbourhood (and, from the origin, above free beams); returns the samples and
// sets the count of ground cells.
std::vector<Sample> GroundSamples(std::span<const Eigen::Vector3f> points, const PillarIndex& index,
                                  const Grid& grid, const GroundOptions& options,
                                  int* ground_cells) {
  const size_t cells = static_cast<size_t>(grid.nx) * grid.ny;
  const std::vector<uint32_t>& start = index.start;
  std::vector<Sample> samples(cells);
  for (int iy = 0; iy < grid.ny; ++iy) {
    for (int ix = 0; ix < grid.nx; ++ix) {
      const size_t c = static_cast<size_t>(iy) * grid.nx + ix;
      if (start[c + 1] - start[c] < static_cast<uint32_t>(options.min_cell_points)) continue;
      const std::span<const uint32_t> members(index.order.data() + start[c],
                                              start[c + 1] - start[c]);
      samples[c] = PillarSample(points, members, grid, ix, iy, options);
    }
  }
  std::vector<Eigen::Vector3f> lowest(
      cells, Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity()));
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].z() < lowest[index.cell_of[i]].z()) lowest[index.cell_of[i]] = points[i];
  }
  *ground_cells = RejectHighSamples(samples, lowest, grid, options);
  if (options.sensor_at_origin) *ground_cells = RejectSamplesAboveFreeBeams(samples, points, grid);
  return samples;
}

// True when the pillar or one of its eight neighbours holds points (bilinear interpolation
// reaches one pillar out).
bool NearPoints(const PillarIndex& index, const Grid& grid, int ix, int iy) {
  for (int jy = std::max(0, iy - 1); jy <= std::min(grid.ny - 1, iy + 1); ++jy) {
    for (int jx = std::max(0, ix - 1); jx <= std::min(grid.nx - 1, ix + 1); ++jx) {
      if (index.Occupied(static_cast<size_t>(jy) * grid.nx + jx)) return true;
    }
  }
  return false;
}

// Heights at the centres of the pillars near points (NaN elsewhere); from the origin, a pillar
// without samples near enough takes the global plane's height.
std::vector<float> CentreHeights(const std::vector<Sample>& samples, const PillarIndex& index,
                                 const Grid& grid, const GroundOptions& options) {
  std::vector<float> heights(static_cast<size_t>(grid.nx) * grid.ny, kNaNf);
  const SampleSums sums(samples, grid);
  Eigen::Vector3d plane;
  const bool with_plane = options.sensor_at_origin && GlobalPlane(samples, &plane);
  for (int iy = 0; iy < grid.ny; ++iy) {
    for (int ix = 0; ix < grid.nx; ++ix) {
      if (!NearPoints(index, grid, ix, iy)) continue;
      float& h = heights[static_cast<size_t>(iy) * grid.nx + ix];
      h = CentreHeight(sums, grid, ix, iy, options.fill_radius);
      if (std::isnan(h) && with_plane) {
        const Eigen::Vector2d c = grid.Centre(ix, iy);
        h = static_cast<float>(plane(0) + plane(1) * c.x() + plane(2) * c.y());
      }
    }
  }
  return heights;
}

// Heights above the lowest point, for a scan without enough ground.
void HeightsAboveLowest(std::span<const Eigen::Vector3f> points, GroundSegmentation& result) {
  float lowest_z = std::numeric_limits<float>::max();
  for (const Eigen::Vector3f& p : points) lowest_z = std::min(lowest_z, p.z());
  result.reference_z = lowest_z;
  for (size_t i = 0; i < points.size(); ++i) result.height[i] = points[i].z() - lowest_z;
}

// Heights above the ground model, and the points below label_height labelled ground.
void LabelPoints(std::span<const Eigen::Vector3f> points, const GroundOptions& options,
                 GroundSegmentation& result) {
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
}

}  // namespace

GroundSegmentation SegmentGround(std::span<const Eigen::Vector3f> points,
                                 const GroundOptions& options) {
  options.Check();
  GroundSegmentation result;
  result.height.assign(points.size(), kNaNf);
  result.is_ground.assign(points.size(), 0);
  if (points.empty()) return result;
  const Grid grid = MakeGrid(points, options);
  const PillarIndex index = SortByPillar(points, grid);
  const std::vector<Sample> samples =
      GroundSamples(points, index, grid, options, &result.ground_cells);
  result.ground_known = result.ground_cells >= options.min_ground_cells;
  if (!result.ground_known) {
    HeightsAboveLowest(points, result);
    return result;
  }
  result.model = GroundModel(grid.min_x, grid.min_y, grid.cell, grid.nx, grid.ny,
                             CentreHeights(samples, index, grid, options));
  LabelPoints(points, options, result);
  return result;
}

}  // namespace forestmap::algorithms
