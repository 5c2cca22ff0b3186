#include "geo/crs.h"

#include <geodesic.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "geo/proj_handles.h"

namespace forestmap::geo {
namespace {

constexpr size_t kMaxCachedCrs = 256;        // distinct CRS texts kept parsed
constexpr double kHeadingStepM = 1.0;        // m: the heading is the azimuth to a point this far
constexpr const char* kWgs84 = "EPSG:4979";  // WGS84 geographic 3-D (lat, lon, h)

using internal::Context;
using internal::PjPtr;

// On the WGS84 ellipsoid, from (lat0, lon0) to (lat1, lon1), degrees: the distance (m) and the
// azimuth at the start (degrees clockwise from north).
struct Geodesic {
  double metres = 0, azimuth_deg = 0;
};
Geodesic Wgs84Inverse(double lat0, double lon0, double lat1, double lon1) {
  static const geod_geodesic wgs84 = [] {
    geod_geodesic g;
    geod_init(&g, 6378137.0, 1 / 298.257223563);  // WGS84 ellipsoid
    return g;
  }();
  Geodesic result;
  double azimuth_end = 0;
  geod_inverse(&wgs84, lat0, lon0, lat1, lon1, &result.metres, &result.azimuth_deg, &azimuth_end);
  return result;
}

// The horizontal part of a CRS: a bound CRS's source, a compound CRS's first component.
PjPtr HorizontalPart(PJ_CONTEXT* ctx, const PJ* crs) {
  PjPtr part(proj_clone(ctx, crs));
  constexpr int kMaxNesting = 3;  // e.g. a bound CRS of a compound CRS
  for (int depth = 0; part && depth < kMaxNesting; ++depth) {
    const PJ_TYPE type = proj_get_type(part.get());
    if (type == PJ_TYPE_BOUND_CRS) {
      part.reset(proj_get_source_crs(ctx, part.get()));
    } else if (type == PJ_TYPE_COMPOUND_CRS) {
      part.reset(proj_crs_get_sub_crs(ctx, part.get(), 0));
    } else {
      break;
    }
  }
  return part;
}

// CrsInfo::map_problem of `crs`.
std::string MapProblem(PJ_CONTEXT* ctx, const PJ* crs) {
  const PjPtr horizontal = HorizontalPart(ctx, crs);
  if (!horizontal) return "PROJ cannot tell its horizontal part";
  switch (proj_get_type(horizontal.get())) {
    case PJ_TYPE_GEOGRAPHIC_CRS:
    case PJ_TYPE_GEOGRAPHIC_2D_CRS:
    case PJ_TYPE_GEOGRAPHIC_3D_CRS:
      return "it is geographic: its coordinates are degrees of longitude and latitude";
    case PJ_TYPE_GEOCENTRIC_CRS:
      return "it is geocentric: its coordinates are earth-centred X, Y, Z";
    case PJ_TYPE_PROJECTED_CRS:
    case PJ_TYPE_ENGINEERING_CRS:
      break;
    default:
      return "it has no horizontal plane";
  }
  const PjPtr cs(proj_crs_get_coordinate_system(ctx, horizontal.get()));
  double to_metre = 0;
  const char* unit = nullptr;
  if (!cs || proj_cs_get_axis_count(ctx, cs.get()) < 2 ||
      !proj_cs_get_axis_info(ctx, cs.get(), 0, nullptr, nullptr, nullptr, &to_metre, &unit, nullptr,
                             nullptr)) {
    return "PROJ cannot tell the unit of its axes";
  }
  if (to_metre == 1.0) return "";
  char factor[32];
  std::snprintf(factor, sizeof factor, "%.10g", to_metre);
  return std::string("its coordinates are in ") + (unit ? unit : "an unnamed unit") + " (" +
         factor + " m), not metres";
}

CrsInfo Parse(const std::string& text) {
  Context context;
  // A PROJ string names a CRS only with +type=crs; users write it without.
  std::string definition = text;
  if (!text.empty() && text[0] == '+' && text.find("+type=crs") == std::string::npos) {
    definition += " +type=crs";
  }
  PjPtr crs(proj_create(context.ctx, definition.c_str()));
  if (!crs) throw CrsError(context.Error());
  if (!proj_is_crs(crs.get())) throw CrsError("it is an operation, not a coordinate system");
  CrsInfo info;
  const char* options[] = {"MULTILINE=NO", nullptr};
  const char* wkt = proj_as_wkt(context.ctx, crs.get(), PJ_WKT2_2019, options);
  if (!wkt) throw CrsError("PROJ cannot write it as WKT: " + context.Error());
  info.wkt = wkt;
  if (const char* name = proj_get_name(crs.get())) info.name = name;
  const PJ_TYPE type = proj_get_type(crs.get());
  info.projected = type == PJ_TYPE_PROJECTED_CRS;
  info.map_problem = MapProblem(context.ctx, crs.get());
  const char* area = nullptr;
  info.has_area = proj_get_area_of_use(context.ctx, crs.get(), &info.west, &info.south, &info.east,
                                       &info.north, &area) &&
                  info.west > -1000;  // PROJ's "unknown"
  if (area) info.area = area;
  const char* authority = proj_get_id_auth_name(crs.get(), 0);
  const char* code = proj_get_id_code(crs.get(), 0);
  if (authority && code && std::string(authority) == "EPSG") {
    info.epsg = std::atoi(code);
  } else {
    // A WKT or PROJ string without an ID: its EPSG twin, when PROJ finds one for certain.
    int* confidence = nullptr;
    PJ_OBJ_LIST* matches = proj_identify(context.ctx, crs.get(), "EPSG", nullptr, &confidence);
    if (matches && proj_list_get_count(matches) > 0 && confidence[0] == 100) {
      PjPtr match(proj_list_get(context.ctx, matches, 0));
      if (const char* c = proj_get_id_code(match.get(), 0)) info.epsg = std::atoi(c);
    }
    proj_int_list_destroy(confidence);
    proj_list_destroy(matches);
  }
  return info;
}

}  // namespace

bool CrsInfo::InArea(double longitude_deg, double latitude_deg, double margin_deg) const {
  if (!has_area) return true;
  if (latitude_deg < south - margin_deg || latitude_deg > north + margin_deg) return false;
  double span = east - west;  // degrees eastwards from west to east
  if (span < 0) span += 360;  // across the antimeridian
  span += 2 * margin_deg;
  if (span >= 360) return true;
  const double start = west - margin_deg;
  const double offset = std::fmod(std::fmod(longitude_deg - start, 360.0) + 360.0, 360.0);
  return offset <= span;
}

std::string CrsInfo::Canonical() const { return epsg > 0 ? "EPSG:" + std::to_string(epsg) : wkt; }

CrsInfo ParseCrs(const std::string& text) {
  static std::mutex mutex;
  static std::map<std::string, CrsInfo> cache;
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (const auto it = cache.find(text); it != cache.end()) return it->second;
  }
  CrsInfo info = Parse(text);
  std::lock_guard<std::mutex> lock(mutex);
  if (cache.size() >= kMaxCachedCrs) cache.clear();
  cache.emplace(text, info);
  return info;
}

struct Reprojection::Impl {
  Context context;
  PjPtr transform;
};

Reprojection::Reprojection(const std::string& from, const std::string& to)
    : impl_(std::make_unique<Impl>()) {
  PJ_CONTEXT* ctx = impl_->context.ctx;
  PjPtr raw(proj_create_crs_to_crs(ctx, from.c_str(), to.c_str(), nullptr));
  if (!raw) {
    throw CrsError("no transformation from '" + from + "' to '" + to +
                   "': " + impl_->context.Error());
  }
  // Easting/northing (longitude/latitude) in and out, whatever the CRSs' axis orders.
  impl_->transform.reset(proj_normalize_for_visualization(ctx, raw.get()));
  if (!impl_->transform) throw CrsError(impl_->context.Error());
}

Reprojection::~Reprojection() = default;

void Reprojection::Apply(double& x, double& y, double& z, Used* used) const {
  std::lock_guard<std::mutex> lock(mutex_);
  PJ* transform = impl_->transform.get();
  const PJ_COORD out = proj_trans(transform, PJ_FWD, proj_coord(x, y, z, 0));
  if (!std::isfinite(out.xyzt.x) || !std::isfinite(out.xyzt.y)) {
    throw CrsError("PROJ cannot transform the point: " + impl_->context.Error());
  }
  if (used) {
    PJ_CONTEXT* ctx = impl_->context.ctx;
    // The operation PROJ chose for this point (of the candidates for the two CRSs).
    const PjPtr operation(proj_trans_get_last_used_operation(transform));
    PJ* op = operation ? operation.get() : transform;
    used->accuracy_m = proj_coordoperation_get_accuracy(ctx, op);
    used->ballpark = proj_coordoperation_has_ballpark_transformation(ctx, op) == 1;
  }
  x = out.xyzt.x;
  y = out.xyzt.y;
  z = out.xyzt.z;
}

std::string UtmZoneCrs(double longitude_deg, double latitude_deg) {
  constexpr double kSouthLimit = -80, kNorthLimit = 84;  // degrees: UTM's domain
  if (!(latitude_deg >= kSouthLimit && latitude_deg <= kNorthLimit) ||
      !std::isfinite(longitude_deg)) {
    throw CrsError("no UTM zone at latitude " + std::to_string(latitude_deg) +
                   " (UTM covers 80 S to 84 N)");
  }
  const double wrapped = std::remainder(longitude_deg, 360.0);  // [-180, 180]
  const int zone = std::clamp(static_cast<int>(std::floor((wrapped + 180) / 6)) + 1, 1, 60);
  return "EPSG:" + std::to_string((latitude_deg >= 0 ? 32600 : 32700) + zone);
}

double GridScaleAt(const std::string& crs, double x, double y) {
  constexpr double kStep = 100.0;  // map units between the two points measured
  const Reprojection to_wgs84(crs, kWgs84);
  double lon0 = x, lat0 = y, z0 = 0, lon1 = x + kStep, lat1 = y, z1 = 0;
  to_wgs84.Apply(lon0, lat0, z0);
  to_wgs84.Apply(lon1, lat1, z1);
  const double metres = Wgs84Inverse(lat0, lon0, lat1, lon1).metres;
  if (!(metres > 0)) throw CrsError("no distance on the ground between two map points");
  return kStep / metres;
}

MapToWgs84::MapToWgs84(const std::string& crs) : to_wgs84_(crs, kWgs84) {}

GeodeticPose MapToWgs84::Convert(double x, double y, double z, double yaw_rad) const {
  double lon = x, lat = y, height = z;
  Reprojection::Used used;
  to_wgs84_.Apply(lon, lat, height, &used);
  double ahead_lon = x + kHeadingStepM * std::cos(yaw_rad);
  double ahead_lat = y + kHeadingStepM * std::sin(yaw_rad), ahead_height = z;
  to_wgs84_.Apply(ahead_lon, ahead_lat, ahead_height);
  GeodeticPose pose;
  pose.longitude_deg = lon;
  pose.latitude_deg = lat;
  pose.ellipsoidal_height_m = height;
  pose.transformation = used;
  const double azimuth = Wgs84Inverse(lat, lon, ahead_lat, ahead_lon).azimuth_deg;
  pose.true_heading_deg = std::fmod(azimuth + 360.0, 360.0);
  const double grid_heading_deg = 90.0 - yaw_rad * 180.0 / M_PI;
  pose.grid_convergence_deg = std::remainder(pose.true_heading_deg - grid_heading_deg, 360.0);
  return pose;
}

}  // namespace forestmap::geo
