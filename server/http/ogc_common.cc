#include "server/http/ogc_common.h"

// clang-format off
#include "server/http/httplib_include.h"
// clang-format on

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <utility>

namespace forestmap::server::ogc {
namespace {

constexpr int kEdgePoints = 16;  // points per edge when a box moves between CRSs

}  // namespace

using Json = nlohmann::json;
using httplib::Request;
using httplib::Response;

MapCrs CrsOf(const storage::MapInfo& info) {
  MapCrs out{info.crs, ""};
  if (out.georeferenced()) {
    const int epsg = geo::ParseCrs(info.crs).epsg;  // cached; stored CRSs are valid
    if (epsg > 0) out.storage_uri = "http://www.opengis.net/def/crs/EPSG/0/" + std::to_string(epsg);
  }
  return out;
}

std::shared_ptr<const geo::Reprojection> ReprojectionOf(const std::string& from,
                                                        const std::string& to) {
  static std::mutex mutex;
  static std::map<std::pair<std::string, std::string>, std::shared_ptr<geo::Reprojection>> made;
  constexpr size_t kMaxKept = 64;  // distinct map CRSs; beyond, start again
  const std::lock_guard lock(mutex);
  const auto key = std::make_pair(from, to);
  if (const auto found = made.find(key); found != made.end()) return found->second;
  if (made.size() >= kMaxKept) made.clear();
  auto created = std::make_shared<geo::Reprojection>(from, to);
  made.emplace(key, created);
  return created;
}

std::optional<std::array<double, 2>> Moved(const geo::Reprojection& projection, double x,
                                           double y) {
  double z = 0;
  try {
    projection.Apply(x, y, z);
  } catch (const geo::CrsError&) {
    return std::nullopt;
  }
  if (!std::isfinite(x) || !std::isfinite(y)) return std::nullopt;
  return std::array<double, 2>{x, y};
}

std::optional<storage::Extent> MovedBox(const geo::Reprojection& projection,
                                        const storage::Extent& box) {
  std::optional<storage::Extent> out;
  for (int i = 0; i <= kEdgePoints; ++i) {
    const double t = static_cast<double>(i) / kEdgePoints;
    const double x = box.min_x + t * (box.max_x - box.min_x);
    const double y = box.min_y + t * (box.max_y - box.min_y);
    for (const auto& [px, py] : std::array<std::array<double, 2>, 4>{
             {{x, box.min_y}, {x, box.max_y}, {box.min_x, y}, {box.max_x, y}}}) {
      const auto moved = Moved(projection, px, py);
      if (!moved) continue;
      if (!out) out = storage::Extent{(*moved)[0], (*moved)[1], (*moved)[0], (*moved)[1]};
      out->min_x = std::min(out->min_x, (*moved)[0]);
      out->min_y = std::min(out->min_y, (*moved)[1]);
      out->max_x = std::max(out->max_x, (*moved)[0]);
      out->max_y = std::max(out->max_y, (*moved)[1]);
    }
  }
  return out;
}

std::string BaseUrl(const Request& request, const std::string& scheme) {
  std::string host = request.get_header_value("Host");
  if (host.empty()) host = request.local_addr + ":" + std::to_string(request.local_port);
  return scheme + "://" + host + "/ogc";
}

Json Link(const std::string& href, const char* rel, const char* type, const std::string& title) {
  Json link = {{"href", href}, {"rel", rel}, {"type", type}};
  if (!title.empty()) link["title"] = title;
  return link;
}

void Reply(Response& response, const Json& body, const char* type) {
  response.set_content(body.dump(-1, ' ', false, Json::error_handler_t::replace), type);
}

// Appended piece by piece: GCC 12 warns, -Wrestrict, about "<" + uri + ">".
void SetContentCrs(Response& response, const std::string& uri) {
  std::string value = "<";
  value += uri;
  value += '>';
  response.set_header("Content-Crs", value);
}

bool IsCrs84(const MapCrs& crs, const std::string& name, const std::string& uri) {
  if (!crs.georeferenced()) {
    throw BadParameter(name + ": this map has no CRS; leave " + name + " out");
  }
  if (uri == kCrs84) return true;
  if (!crs.storage_uri.empty() && uri == crs.storage_uri) return false;
  throw BadParameter(name + "=" + uri + ": give " + kCrs84 +
                     (crs.storage_uri.empty() ? "" : " or " + crs.storage_uri));
}

}  // namespace forestmap::server::ogc
