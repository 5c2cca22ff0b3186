#include "geo/crs.h"

#include <geodesic.h>
#include <proj.h>

#include <cmath>
#include <map>

namespace forestmap::geo {
namespace {

constexpr size_t kMaxCachedCrs = 256;        // distinct CRS texts kept parsed
constexpr double kHeadingStepM = 1.0;        // m: the heading is the azimuth to a point this far
constexpr const char* kWgs84 = "EPSG:4979";  // WGS84 geographic 3-D (lat, lon, h)

// A PROJ context of our own: its errors are read here, never logged by PROJ.
struct Context {
  Context() : ctx(proj_context_create()) { proj_log_level(ctx, PJ_LOG_NONE); }
  ~Context() { proj_context_destroy(ctx); }
  std::string Error() const { return proj_context_errno_string(ctx, proj_context_errno(ctx)); }
  PJ_CONTEXT* ctx;
};

struct PjDeleter {
  void operator()(PJ* pj) const { proj_destroy(pj); }
};
using PjPtr = std::unique_ptr<PJ, PjDeleter>;

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

struct MapToWgs84::Impl {
  Context context;
  PjPtr transform;
  geod_geodesic wgs84;
};

MapToWgs84::MapToWgs84(const std::string& crs) : impl_(std::make_unique<Impl>()) {
  PJ_CONTEXT* ctx = impl_->context.ctx;
  PjPtr raw(proj_create_crs_to_crs(ctx, crs.c_str(), kWgs84, nullptr));
  if (!raw)
    throw CrsError("no transformation from '" + crs + "' to WGS84: " + impl_->context.Error());
  // Easting/northing in, longitude/latitude out, whatever the CRSs' axis orders.
  impl_->transform.reset(proj_normalize_for_visualization(ctx, raw.get()));
  if (!impl_->transform) throw CrsError(impl_->context.Error());
  geod_init(&impl_->wgs84, 6378137.0, 1 / 298.257223563);  // WGS84 ellipsoid
}

MapToWgs84::~MapToWgs84() = default;

GeodeticPose MapToWgs84::Convert(double x, double y, double z, double yaw_rad) const {
  std::lock_guard<std::mutex> lock(mutex_);
  PJ* transform = impl_->transform.get();
  const PJ_COORD at = proj_trans(transform, PJ_FWD, proj_coord(x, y, z, 0));
  const PJ_COORD ahead = proj_trans(transform, PJ_FWD,
                                    proj_coord(x + kHeadingStepM * std::cos(yaw_rad),
                                               y + kHeadingStepM * std::sin(yaw_rad), z, 0));
  if (!std::isfinite(at.lpzt.lam) || !std::isfinite(ahead.lpzt.lam)) {
    throw CrsError("PROJ cannot transform the point: " + impl_->context.Error());
  }
  GeodeticPose pose;
  pose.longitude_deg = at.lpzt.lam;
  pose.latitude_deg = at.lpzt.phi;
  pose.ellipsoidal_height_m = at.lpzt.z;
  double distance = 0, azimuth = 0, azimuth_end = 0;
  geod_inverse(&impl_->wgs84, at.lpzt.phi, at.lpzt.lam, ahead.lpzt.phi, ahead.lpzt.lam, &distance,
               &azimuth, &azimuth_end);
  pose.true_heading_deg = std::fmod(azimuth + 360.0, 360.0);
  const double grid_heading_deg = 90.0 - yaw_rad * 180.0 / M_PI;
  pose.grid_convergence_deg = std::remainder(pose.true_heading_deg - grid_heading_deg, 360.0);
  return pose;
}

}  // namespace forestmap::geo
