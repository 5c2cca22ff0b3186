#include "server/http/ogc_boundary.h"

// clang-format off
#include "server/http/httplib_include.h"
// clang-format on

#include <algorithm>
#include <set>

#include "server/http/http_trees.h"
#include "server/http/ogc_common.h"
#include "server/http/ogc_documents.h"

namespace forestmap::server::ogc {

using Json = nlohmann::json;

namespace {

// The boundary's GeoJSON MultiPolygon coordinates (rings closed) moved by `to` (null: as stored),
// and their bounding box; nullopt when a vertex is off the CRS's domain.
struct Coordinates {
  Json polygons = Json::array();
  storage::Extent box;
};
std::optional<Coordinates> CoordinatesOf(const storage::Boundary& boundary,
                                         const geo::Reprojection* to) {
  Coordinates out;
  bool first = true;
  for (const storage::BoundaryPolygon& polygon : boundary) {
    Json rings = Json::array();
    for (size_t r = 0; r <= polygon.holes.size(); ++r) {
      const storage::BoundaryRing& ring = r == 0 ? polygon.outer : polygon.holes[r - 1];
      Json points = Json::array();
      for (size_t i = 0; i <= ring.size(); ++i) {
        const storage::BoundaryPoint& p = ring[i % ring.size()];  // closed: the first again
        std::optional<std::array<double, 2>> xy = std::array<double, 2>{p.x, p.y};
        if (to) xy = Moved(*to, p.x, p.y);
        if (!xy) return std::nullopt;
        const auto [x, y] = *xy;
        if (first) out.box = {x, y, x, y};
        first = false;
        out.box = {std::min(out.box.min_x, x), std::min(out.box.min_y, y),
                   std::max(out.box.max_x, x), std::max(out.box.max_y, y)};
        points.push_back({x, y});
      }
      rings.push_back(std::move(points));
    }
    out.polygons.push_back(std::move(rings));
  }
  return out;
}

bool Overlap(const storage::Extent& a, const storage::Extent& b) {
  return a.min_x <= b.max_x && b.min_x <= a.max_x && a.min_y <= b.max_y && b.min_y <= a.max_y;
}

// The feature in CRS84 (`crs84`) or the map's own coordinates.
Json Feature(const storage::MapInfo& info, const storage::Boundary& boundary, bool crs84) {
  const std::optional<Coordinates> coordinates =
      CoordinatesOf(boundary, crs84 ? ReprojectionOf(info.crs, kCrs84Proj).get() : nullptr);
  Json geometry = nullptr;
  if (coordinates) geometry = {{"type", "MultiPolygon"}, {"coordinates", coordinates->polygons}};
  return {{"type", "Feature"},
          {"id", 1},
          {"geometry", std::move(geometry)},
          {"properties",
           {{"map", info.name}, {"version", info.version}, {"polygons", boundary.size()}}}};
}

}  // namespace

std::string BoundaryCollectionId(const std::string& map) { return map + kBoundarySuffix; }

Json BoundaryCollectionJson(const storage::MapInfo& info, const storage::Boundary& boundary,
                            const std::string& base) {
  const MapCrs crs = CrsOf(info);
  const std::string id = BoundaryCollectionId(info.name);
  const std::string self = base + "/collections/" + id;
  Json collection = {{"id", id},
                     {"title", info.name + " survey boundary"},
                     {"description", "The area the survey of map '" + info.name + "' covered"},
                     {"itemType", "feature"},
                     {"links",
                      {Link(self, "self", "application/json", ""),
                       Link(self + "/items", "items", kGeoJson, info.name + ": survey boundary"),
                       Link(base + "/collections/" + info.name, "related", "application/json",
                            info.name + ": trees")}}};
  if (crs.georeferenced()) {
    collection["crs"] = {kCrs84};
    if (!crs.storage_uri.empty()) {
      collection["crs"].push_back(crs.storage_uri);
      collection["storageCrs"] = crs.storage_uri;
    }
    const std::optional<Coordinates> lonlat =
        CoordinatesOf(boundary, ReprojectionOf(info.crs, kCrs84Proj).get());
    if (lonlat) {
      const storage::Extent& b = lonlat->box;
      collection["extent"]["spatial"] = {{"bbox", {{b.min_x, b.min_y, b.max_x, b.max_y}}},
                                         {"crs", kCrs84}};
    }
  }
  return collection;
}

void ReplyBoundaryItems(const httplib::Request& request, httplib::Response& response,
                        const storage::MapInfo& info, const storage::Boundary& boundary,
                        const std::string& base, std::optional<int64_t> feature) {
  static const std::set<std::string> kKnown = {"limit", "bbox", "bbox-crs", "crs", "f"};
  for (const auto& [name, value] : request.params) {
    if (!kKnown.contains(name) || (feature && name != "crs" && name != "f")) {
      throw BadParameter("unknown parameter " + name);
    }
  }
  const MapCrs crs = CrsOf(info);
  const auto crs84 = [&](const char* name) {
    return request.has_param(name) ? IsCrs84(crs, name, request.get_param_value(name))
                                   : crs.georeferenced();
  };
  const bool out_crs84 = crs84("crs");
  const std::string format = request.get_param_value("f");
  if (!format.empty() && format != "json" && format != "geojson") {
    throw BadParameter("f=" + format + ": give json");
  }
  if (crs.georeferenced()) SetContentCrs(response, out_crs84 ? kCrs84 : crs.storage_uri);
  if (feature) {
    if (*feature != 1) {
      response.status = 404;
      Reply(response, Json{{"code", "NotFound"},
                           {"description",
                            "the boundary of map '" + info.name + "' is feature 1, the only one"}});
      return;
    }
    Reply(response, Feature(info, boundary, out_crs84), kGeoJson);
    return;
  }
  if (request.has_param("limit")) {
    const std::string limit = request.get_param_value("limit");
    if (limit.empty() || limit.find_first_not_of("0123456789") != std::string::npos ||
        limit.size() > 6 || std::stoi(limit) < 1) {
      throw BadParameter("limit=" + limit + ": give an integer from 1");
    }
  }
  Json features = Json::array();
  bool inside = true;
  if (request.has_param("bbox")) {
    const storage::Extent bbox = ParseBox("bbox", request.get_param_value("bbox"));
    const bool bbox_crs84 = crs84("bbox-crs");
    const std::optional<Coordinates> in_bbox_crs =
        CoordinatesOf(boundary, bbox_crs84 ? ReprojectionOf(info.crs, kCrs84Proj).get() : nullptr);
    inside = in_bbox_crs && Overlap(in_bbox_crs->box, bbox);
  } else if (request.has_param("bbox-crs")) {
    crs84("bbox-crs");  // checked all the same
  }
  if (inside) features.push_back(Feature(info, boundary, out_crs84));
  const std::string self = base + "/collections/" + BoundaryCollectionId(info.name);
  Reply(response,
        Json{{"type", "FeatureCollection"},
             {"numberMatched", features.size()},
             {"numberReturned", features.size()},
             {"links",
              {Link(self + "/items", "self", kGeoJson, ""),
               Link(self, "collection", "application/json", "")}},
             {"features", std::move(features)}},
        kGeoJson);
}

}  // namespace forestmap::server::ogc
