// Ray casting in a ForestScene: exact ray/cone, ray/cylinder and ray/ellipsoid intersections, a
// beam-footprint model for stem edges, and a 2-D grid march (Amanatides & Woo 1987, "A fast voxel
// traversal algorithm for ray tracing") over the scene's cells.

#include <algorithm>
#include <cmath>

#include "algorithms/core/random.h"
#include "algorithms/simulation/forest_scene.h"

namespace forestmap::algorithms {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMinT = 1e-6;  // m, hits nearer than this along the ray are ignored

// Uniform in [0, 1) from (key, salt), stateless (SplitMix64), so that a ray's random draws for one
// primitive are the same however often (and in whichever cell) the primitive is tested.
double HashUniform(uint64_t key, uint64_t salt) {
  return static_cast<double>(SplitMix64(key ^ SplitMix64(salt)) >> 11) * 0x1.0p-53;
}

// Smallest root of a t^2 + b t + c in [lo, hi], or inf.
double SmallestRoot(double a, double b, double c, double lo, double hi) {
  double r1 = kInf, r2 = kInf;
  if (std::abs(a) < 1e-12) {
    if (std::abs(b) < 1e-15) return kInf;
    r1 = -c / b;
  } else {
    const double disc = b * b - 4 * a * c;
    if (disc < 0) return kInf;
    const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
    r1 = q / a;
    r2 = q != 0 ? c / q : kInf;
    if (r1 > r2) std::swap(r1, r2);
  }
  if (r1 >= lo && r1 <= hi) return r1;
  if (r2 >= lo && r2 <= hi) return r2;
  return kInf;
}

// Entry of the ray into the side of a cone (or cylinder) whose radius at s is
// radius + extra + radius_slope * s, s in [0, length]; inf when it misses. A ray starting inside
// the cone does not hit it (its entry would be behind the origin).
double ConeEntry(const ScenePrimitive& p, const Ray& ray, double extra) {
  const Eigen::Vector3d w0 = ray.origin - p.origin;
  const double s0 = w0.dot(p.axis);
  const double ds = ray.direction.dot(p.axis);
  const double k = p.radius_slope;
  const double q = p.radius + extra + k * s0;
  const double a = 1 - ds * ds - k * k * ds * ds;
  const double b = 2 * (w0.dot(ray.direction) - s0 * ds) - 2 * q * k * ds;
  const double c = w0.squaredNorm() - s0 * s0 - q * q;
  if (c <= 0 && s0 >= 0 && s0 <= p.length && q > 0) return kInf;  // origin inside
  double roots[2] = {kInf, kInf};
  if (std::abs(a) < 1e-12) {
    if (std::abs(b) > 1e-15) roots[0] = -c / b;
  } else {
    const double disc = b * b - 4 * a * c;
    if (disc < 0) return kInf;
    const double sq = std::copysign(std::sqrt(disc), b);
    const double qq = -0.5 * (b + sq);
    roots[0] = qq / a;
    roots[1] = qq != 0 ? c / qq : kInf;
    if (roots[0] > roots[1]) std::swap(roots[0], roots[1]);
  }
  for (double t : roots) {
    if (!(t > kMinT) || !std::isfinite(t)) continue;
    const double s = s0 + t * ds;
    if (s >= 0 && s <= p.length && q + k * ds * t > 0) return t;
  }
  return kInf;
}

// Entry and exit of the ray through an axis-aligned ellipsoid; false when it misses.
bool EllipsoidSpan(const ScenePrimitive& p, const Ray& ray, double* t_in, double* t_out) {
  const Eigen::Vector3d o = (ray.origin - p.origin).cwiseQuotient(p.size);
  const Eigen::Vector3d d = ray.direction.cwiseQuotient(p.size);
  const double a = d.squaredNorm(), b = 2 * o.dot(d), c = o.squaredNorm() - 1;
  const double disc = b * b - 4 * a * c;
  if (disc <= 0) return false;
  const double sq = std::sqrt(disc);
  *t_in = (-b - sq) / (2 * a);
  *t_out = (-b + sq) / (2 * a);
  return *t_out > kMinT;
}

void Offer(double t, const ScenePrimitive& p, int index, bool partial, RayHit* best) {
  if (t > kMinT && t < best->range) {
    best->range = t;
    best->label = p.label;
    best->primitive = index;
    best->partial = partial;
  }
}

}  // namespace

void ForestScene::TestPrimitive(const Ray& ray, int index, RayHit* best) const {
  const ScenePrimitive& p = primitives_[index];
  switch (p.kind) {
    case ScenePrimitive::Kind::kVolume: {
      double t_in = 0, t_out = 0;
      if (!EllipsoidSpan(p, ray, &t_in, &t_out)) return;
      t_in = std::max(t_in, kMinT);
      if (t_in >= best->range) return;
      // Beer-Lambert: free path inside the volume is exponential with rate `extinction`.
      const double u = HashUniform(ray.key, 2 * static_cast<uint64_t>(index));
      const double t = t_in - std::log1p(-u) / p.extinction;
      if (t < t_out) Offer(t, p, index, false, best);
      return;
    }
    case ScenePrimitive::Kind::kCylinder: {
      // Thin branches return once about half of the footprint covers them.
      const double distance = (p.origin - ray.origin).norm();
      Offer(ConeEntry(p, ray, 0.5 * ray.footprint_per_m * distance), p, index, false, best);
      return;
    }
    case ScenePrimitive::Kind::kCone:
      break;
  }
  // Closest approach of the beam's centre line to the stem axis: rejects most stems at once.
  const Eigen::Vector3d w0 = ray.origin - p.origin;
  const double b = ray.direction.dot(p.axis);
  const double sin2 = 1 - b * b;
  const double t_c = sin2 > 1e-9 ? (b * w0.dot(p.axis) - w0.dot(ray.direction)) / sin2 : 0;
  const double s_c = w0.dot(p.axis) + b * t_c;
  const double miss = (w0 + t_c * ray.direction - s_c * p.axis).norm();
  const double footprint = ray.footprint_per_m * std::max(t_c, 0.0);
  if (sin2 > 1e-9 && miss >= p.radius + footprint) return;  // p.radius: the widest (base)
  const double core = ConeEntry(p, ray, 0);
  if (std::isfinite(core)) {
    Offer(core, p, index, false, best);
    return;
  }
  // Beams nearly along the stem: the footprint model does not apply.
  if (ray.footprint_per_m <= 0 || sin2 < 0.01) return;
  if (t_c <= kMinT || s_c < 0 || s_c > p.length) return;
  const double radius = p.radius + p.radius_slope * s_c;
  if (miss >= radius + footprint) return;
  // The footprint touches the stem: it returns with probability rising from 0 (just touching)
  // to 1 (half covered); the range is that of the nearest covered part of the stem.
  const double covered = (radius + footprint - miss) / footprint;
  const double chord =
      std::sqrt(std::max(0.0, radius * radius - (miss - footprint) * (miss - footprint)));
  const double t_edge = t_c - chord / std::sqrt(sin2);
  if (t_edge <= kMinT || t_edge >= best->range) return;
  if (HashUniform(ray.key, 2 * static_cast<uint64_t>(index) + 1) < covered) {
    Offer(t_edge, p, index, true, best);
  } else if (t_edge < best->edge_range) {
    best->edge_range = t_edge;
    best->edge_primitive = index;
    best->edge_fraction = std::clamp(0.5 * covered, 0.0, 1.0);
  }
}

double ForestScene::TerrainHitInCell(const Ray& ray, int cx, int cy, double t0, double t1) const {
  const double cell = options_.cell_size;
  const double h00 = NodeHeight(cx, cy), h10 = NodeHeight(cx + 1, cy);
  const double h01 = NodeHeight(cx, cy + 1), h11 = NodeHeight(cx + 1, cy + 1);
  const double z_a = ray.origin.z() + ray.direction.z() * t0;
  const double z_b = ray.origin.z() + ray.direction.z() * t1;
  if (std::min(z_a, z_b) > std::max({h00, h10, h01, h11})) return kInf;
  // Bilinear height along the ray is quadratic in t: solve z_ray(t) - h(t) = 0.
  const double u0 = (ray.origin.x() - min_corner_.x()) / cell - cx;
  const double v0 = (ray.origin.y() - min_corner_.y()) / cell - cy;
  const double du = ray.direction.x() / cell, dv = ray.direction.y() / cell;
  const double ga = h10 - h00, gb = h01 - h00, ge = h11 - h10 - h01 + h00;
  const double a = -ge * du * dv;
  const double b = ray.direction.z() - ga * du - gb * dv - ge * (u0 * dv + v0 * du);
  const double c = ray.origin.z() - h00 - ga * u0 - gb * v0 - ge * u0 * v0;
  if (a * t0 * t0 + b * t0 + c <= 0) return std::max(t0, kMinT);  // starts below the ground
  return SmallestRoot(a, b, c, t0, t1);
}

namespace {

// Clips [0, max_range] of the ray to the xy box [lo, hi]; false when nothing is left.
bool ClipToBox(const Ray& ray, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double* t0,
               double* t1) {
  *t0 = 0;
  *t1 = ray.max_range;
  for (int axis = 0; axis < 2; ++axis) {
    const double o = ray.origin[axis], d = ray.direction[axis];
    if (std::abs(d) < 1e-12) {
      if (o < lo[axis] || o > hi[axis]) return false;
      continue;
    }
    double a = (lo[axis] - o) / d, b = (hi[axis] - o) / d;
    if (a > b) std::swap(a, b);
    *t0 = std::max(*t0, a);
    *t1 = std::min(*t1, b);
  }
  return *t0 <= *t1;
}

void OfferTerrain(double t, RayHit* best) {
  if (t < best->range) {
    best->range = t;
    best->label = kLabelGround;
    best->primitive = -1;
    best->partial = false;
  }
}

// Hits beyond the scanner's range are no return (the edge record stays, for mixed pixels).
RayHit WithinRange(RayHit best, double max_range) {
  if (best.range > max_range) {
    best.range = kInf;
    best.label = kLabelNoReturn;
    best.primitive = -1;
    best.partial = false;
  }
  return best;
}

}  // namespace

RayHit ForestScene::CastRay(const Ray& ray) const {
  RayHit best;
  double t = 0, t_hi = 0;
  if (!ClipToBox(ray, min_corner_, max_corner_, &t, &t_hi)) return best;
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  // Amanatides-Woo: the cell holding the ray at t, and the t of its next x and y cell borders.
  const double cell = options_.cell_size;
  const Eigen::Vector3d start = o + t * d;
  int cx = std::clamp(int(std::floor((start.x() - min_corner_.x()) / cell)), 0, nx_ - 1);
  int cy = std::clamp(int(std::floor((start.y() - min_corner_.y()) / cell)), 0, ny_ - 1);
  const int step_x = d.x() > 0 ? 1 : -1, step_y = d.y() > 0 ? 1 : -1;
  const bool moves_x = std::abs(d.x()) > 1e-12, moves_y = std::abs(d.y()) > 1e-12;
  const double delta_x = moves_x ? cell / std::abs(d.x()) : kInf;
  const double delta_y = moves_y ? cell / std::abs(d.y()) : kInf;
  double next_x = moves_x ? (min_corner_.x() + (cx + (step_x > 0)) * cell - o.x()) / d.x() : kInf;
  double next_y = moves_y ? (min_corner_.y() + (cy + (step_y > 0)) * cell - o.y()) / d.y() : kInf;
  while (true) {
    const double t_end = std::min({next_x, next_y, t_hi});
    const size_t c = static_cast<size_t>(cy) * nx_ + cx;
    const double z_a = o.z() + d.z() * t, z_b = o.z() + d.z() * t_end;
    if (d.z() >= 0 && z_a > scene_top_) break;  // above everything and rising
    if (std::min(z_a, z_b) <= cell_top_[c]) {
      OfferTerrain(TerrainHitInCell(ray, cx, cy, t, t_end), &best);
      const float z_low = static_cast<float>(std::min(z_a, z_b));
      const float z_high = static_cast<float>(std::max(z_a, z_b));
      for (int i = cell_start_[c]; i < cell_start_[c + 1]; ++i) {
        const int item = cell_items_[i];
        // The ray passes this cell entirely above or below the primitive.
        if (z_high < primitive_z_[item].x() || z_low > primitive_z_[item].y()) continue;
        TestPrimitive(ray, item, &best);
      }
    }
    // Hits in later cells lie farther than t_end: the first cell with a hit decides.
    if (best.range <= t_end || t_end >= t_hi) break;
    if (next_x < next_y) {
      cx += step_x;
      t = next_x;
      next_x += delta_x;
    } else {
      cy += step_y;
      t = next_y;
      next_y += delta_y;
    }
    if (cx < 0 || cx >= nx_ || cy < 0 || cy >= ny_) break;
  }
  return WithinRange(best, ray.max_range);
}

RayHit ForestScene::CastRayBruteForce(const Ray& ray) const {
  RayHit best;
  for (size_t i = 0; i < primitives_.size(); ++i) TestPrimitive(ray, static_cast<int>(i), &best);
  const double cell = options_.cell_size;
  for (int cy = 0; cy < ny_; ++cy) {
    for (int cx = 0; cx < nx_; ++cx) {
      const Eigen::Vector2d lo = min_corner_ + cell * Eigen::Vector2d(cx, cy);
      double t0 = 0, t1 = 0;
      if (!ClipToBox(ray, lo, lo + Eigen::Vector2d::Constant(cell), &t0, &t1)) continue;
      OfferTerrain(TerrainHitInCell(ray, cx, cy, t0, t1), &best);
    }
  }
  return WithinRange(best, ray.max_range);
}

}  // namespace forestmap::algorithms
