#pragma once
// Pieces that the routes of OGC API - Features (server/http/ogc_features.h) share: the CRSs a map
// offers and the moves between them, links, and JSON answers.

#include <array>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>

#include "geo/crs.h"
#include "storage/map_store.h"

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace forestmap::server::ogc {

inline constexpr const char* kCrs84 = "http://www.opengis.net/def/crs/OGC/1.3/CRS84";
inline constexpr const char* kCrs84Proj = "OGC:CRS84";  // the same CRS as PROJ names it

// A 400 with OGC's exception body.
struct BadParameter : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

// The CRSs a map offers: CRS84 when it has a CRS (then the default), its EPSG CRS when it has one.
struct MapCrs {
  std::string crs;          // the map's own (MapInfo::crs), "" for none
  std::string storage_uri;  // "http://www.opengis.net/def/crs/EPSG/0/n", "" when no EPSG code
  bool georeferenced() const { return !crs.empty(); }
};
MapCrs CrsOf(const storage::MapInfo& info);

// Whether `uri` (a crs or bbox-crs value) names CRS84 (true) or the storage CRS (false);
// BadParameter naming `name` otherwise.
bool IsCrs84(const MapCrs& crs, const std::string& name, const std::string& uri);

// PROJ transformations by (from, to), made once: creating one takes milliseconds.
std::shared_ptr<const geo::Reprojection> ReprojectionOf(const std::string& from,
                                                        const std::string& to);
// x, y moved by `projection`; nullopt off its domain.
std::optional<std::array<double, 2>> Moved(const geo::Reprojection& projection, double x, double y);
// The box around `box` moved by `projection`, its edges sampled; nullopt when no point moves.
std::optional<storage::Extent> MovedBox(const geo::Reprojection& projection,
                                        const storage::Extent& box);

// "SCHEME://<Host header>/ogc".
std::string BaseUrl(const httplib::Request& request, const std::string& scheme);
nlohmann::json Link(const std::string& href, const char* rel, const char* type,
                    const std::string& title);
void Reply(httplib::Response& response, const nlohmann::json& body,
           const char* type = "application/json");
// The Content-Crs header of a feature answer: <uri>.
void SetContentCrs(httplib::Response& response, const std::string& uri);

}  // namespace forestmap::server::ogc
