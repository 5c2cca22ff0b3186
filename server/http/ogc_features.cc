#include "server/http/ogc_features.h"

// clang-format off
#include <httplib.h>
// clang-format on

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "geo/crs.h"
#include "server/http/http_route.h"
#include "server/http/http_trees.h"
#include "server/http/ogc_documents.h"
#include "server/http/page_auth.h"
#include "storage/staged_writes.h"

namespace forestmap::server {
namespace {

using Json = nlohmann::json;
using httplib::Request;
using httplib::Response;

constexpr const char* kCrs84 = "http://www.opengis.net/def/crs/OGC/1.3/CRS84";
constexpr const char* kCrs84Proj = "OGC:CRS84";  // the same CRS as PROJ names it
constexpr int kEdgePoints = 16;
constexpr double kNaN =
    std::numeric_limits<double>::quiet_NaN();  // points per edge when a box moves between CRSs

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

MapCrs CrsOf(const storage::MapInfo& info) {
  MapCrs out{info.crs, ""};
  if (out.georeferenced()) {
    const int epsg = geo::ParseCrs(info.crs).epsg;  // cached; stored CRSs are valid
    if (epsg > 0) out.storage_uri = "http://www.opengis.net/def/crs/EPSG/0/" + std::to_string(epsg);
  }
  return out;
}

// PROJ transformations by (from, to), made once: creating one takes milliseconds.
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

// x, y moved by `projection`; nullopt off its domain.
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

// The box around `box` moved by `projection`, its edges sampled; nullopt when no point moves.
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

void Reply(Response& response, const Json& body, const char* type = "application/json") {
  response.set_content(body.dump(-1, ' ', false, Json::error_handler_t::replace), type);
}

// The Content-Crs header of a feature answer: <uri> (appended piece by piece: GCC 12 warns,
// -Wrestrict, about "<" + uri + ">").
void SetContentCrs(Response& response, const std::string& uri) {
  std::string value = "<";
  value += uri;
  value += '>';
  response.set_header("Content-Crs", value);
}

// Runs `body`: BadParameter -> 400, a store or CRS error (unknown map, ...) -> 404.
template <typename Body>
void Answer(Response& response, Body body) {
  try {
    body();
  } catch (const std::invalid_argument& e) {  // BadParameter, ParseBox
    response.status = 400;
    Reply(response, Json{{"code", "InvalidParameterValue"}, {"description", e.what()}});
  } catch (const std::exception& e) {
    response.status = 404;
    Reply(response, Json{{"code", "NotFound"}, {"description", e.what()}});
  }
}

int64_t ParseInteger(const std::string& name, const std::string& text, int64_t min, int64_t max) {
  int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value < min || value > max) {
    throw BadParameter(name + "=" + text + ": give an integer from " + std::to_string(min) +
                       " to " + std::to_string(max));
  }
  return value;
}

// Whether `uri` (a crs or bbox-crs value) names CRS84 (true) or the storage CRS (false).
bool IsCrs84(const MapCrs& crs, const std::string& name, const std::string& uri) {
  if (!crs.georeferenced()) {
    throw BadParameter(name + ": this map has no CRS; leave " + name + " out");
  }
  if (uri == kCrs84) return true;
  if (!crs.storage_uri.empty() && uri == crs.storage_uri) return false;
  throw BadParameter(name + "=" + uri + ": give " + kCrs84 +
                     (crs.storage_uri.empty() ? "" : " or " + crs.storage_uri));
}

Json CollectionJson(const storage::MapInfo& info, const std::string& base) {
  const MapCrs crs = CrsOf(info);
  const std::string self = base + "/collections/" + info.name;
  Json collection = {{"id", info.name},
                     {"title", info.name},
                     {"description", info.description},
                     {"itemType", "feature"},
                     {"links",
                      {Link(self, "self", "application/json", ""),
                       Link(self + "/items", "items", kGeoJson, info.name + ": trees")}}};
  if (crs.georeferenced()) {
    collection["crs"] = {kCrs84};
    if (!crs.storage_uri.empty()) {
      collection["crs"].push_back(crs.storage_uri);
      collection["storageCrs"] = crs.storage_uri;
    }
    if (info.extent) {
      const auto box = MovedBox(*ReprojectionOf(info.crs, kCrs84Proj), *info.extent);
      if (box) {
        collection["extent"]["spatial"] = {
            {"bbox", {{box->min_x, box->min_y, box->max_x, box->max_y}}}, {"crs", kCrs84}};
      }
    }
  }
  return collection;
}

// The items request, checked.
struct ItemsQuery {
  int64_t limit = kOgcDefaultLimit;
  std::optional<storage::Extent> bbox;  // in the bbox's CRS
  bool bbox_crs84 = false;
  bool out_crs84 = false;
  std::optional<int64_t> after;
  std::optional<int64_t> version;
};

ItemsQuery ParseItems(const Request& request, const MapCrs& crs) {
  static const std::set<std::string> kKnown = {"limit", "bbox",    "bbox-crs", "crs",
                                               "after", "version", "f"};
  for (const auto& [name, value] : request.params) {
    if (!kKnown.contains(name)) throw BadParameter("unknown parameter " + name);
  }
  ItemsQuery query;
  query.bbox_crs84 = query.out_crs84 = crs.georeferenced();
  if (request.has_param("limit")) {
    query.limit = ParseInteger("limit", request.get_param_value("limit"), 1, kOgcMaxLimit);
  }
  if (request.has_param("crs"))
    query.out_crs84 = IsCrs84(crs, "crs", request.get_param_value("crs"));
  if (request.has_param("bbox")) query.bbox = ParseBox("bbox", request.get_param_value("bbox"));
  if (request.has_param("bbox-crs")) {
    query.bbox_crs84 = IsCrs84(crs, "bbox-crs", request.get_param_value("bbox-crs"));
  }
  if (request.has_param("after")) {
    query.after = ParseInteger("after", request.get_param_value("after"), INT64_MIN, INT64_MAX);
  }
  if (request.has_param("version")) {
    query.version = ParseInteger("version", request.get_param_value("version"), 1, INT64_MAX);
  }
  const std::string format = request.get_param_value("f");
  if (!format.empty() && format != "json" && format != "geojson") {
    throw BadParameter("f=" + format + ": give json");
  }
  return query;
}

std::string NowRfc3339() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

// The next page's address: the request's own parameters, the cursor and version pinned.
std::string NextHref(const Request& request, const std::string& items, int64_t after,
                     int64_t version) {
  httplib::Params params;
  for (const auto& [name, value] : request.params) {
    if (name != "after" && name != "version") params.emplace(name, value);
  }
  params.emplace("after", std::to_string(after));
  params.emplace("version", std::to_string(version));
  return items + "?" + httplib::detail::params_to_query_str(params);
}

void ReplyItems(const Request& request, Response& response, storage::MapStore& store,
                const storage::MapInfo& info, const std::string& base) {
  const MapCrs crs = CrsOf(info);
  const ItemsQuery query = ParseItems(request, crs);
  // Longitude, latitude of each tree only when the answer or the bbox is in CRS84.
  std::shared_ptr<const geo::Reprojection> to_crs84;
  if (query.out_crs84 || (query.bbox && query.bbox_crs84)) {
    to_crs84 = ReprojectionOf(info.crs, kCrs84Proj);
  }
  storage::TreePageQuery page_query;
  page_query.version = query.version.value_or(info.version);
  page_query.created_unix_ms = info.created_unix_ms;
  page_query.after_id = query.after;
  page_query.limit = query.limit;
  if (query.bbox) {  // the store's box in map coordinates; trees then checked in the bbox's CRS
    page_query.box = query.bbox_crs84 ? MovedBox(*ReprojectionOf(kCrs84Proj, info.crs), *query.bbox)
                                      : query.bbox;
  }
  std::vector<storage::TreeRecord> page;
  if (!query.bbox || page_query.box) page = store.ReadTreesPage(info.name, page_query);
  const bool more = static_cast<int64_t>(page.size()) == query.limit;  // a next page may follow
  const int64_t last_id = page.empty() ? 0 : *page.back().id;
  auto stream = std::make_shared<ItemsStream>();
  for (storage::TreeRecord& tree : page) {
    std::optional<std::array<double, 2>> lonlat;
    if (to_crs84) lonlat = Moved(*to_crs84, tree.x, tree.y);
    if (query.bbox && query.bbox_crs84) {
      const storage::Extent& b = *query.bbox;
      if (!lonlat || (*lonlat)[0] < b.min_x || (*lonlat)[0] > b.max_x || (*lonlat)[1] < b.min_y ||
          (*lonlat)[1] > b.max_y) {
        continue;
      }
    }
    stream->xy.push_back(query.out_crs84 ? lonlat
                                         : std::optional(std::array<double, 2>{tree.x, tree.y}));
    stream->trees.push_back(std::move(tree));
  }
  const std::string items = base + "/collections/" + info.name + "/items";
  Json links = {Link(items, "self", kGeoJson, ""),
                Link(base + "/collections/" + info.name, "collection", "application/json", "")};
  if (more) {
    links.push_back(
        Link(NextHref(request, items, last_id, page_query.version), "next", kGeoJson, "next page"));
  }
  if (crs.georeferenced()) {
    SetContentCrs(response, query.out_crs84 ? kCrs84 : crs.storage_uri);
  }
  stream->head = R"({"type":"FeatureCollection","numberReturned":)" +
                 std::to_string(stream->trees.size()) + R"(,"timeStamp":")" + NowRfc3339() +
                 R"(","links":)" + links.dump() + R"(,"features":[)";
  response.set_chunked_content_provider(
      kGeoJson, [stream](size_t, httplib::DataSink& sink) { return stream->Write(sink); });
}

// One tree by id: the first tree after id - 1, when it is that one.
void ReplyItem(const Request& request, Response& response, storage::MapStore& store,
               const storage::MapInfo& info, int64_t id) {
  const MapCrs crs = CrsOf(info);
  const bool crs84 = request.has_param("crs") ? IsCrs84(crs, "crs", request.get_param_value("crs"))
                                              : crs.georeferenced();
  storage::TreePageQuery query;
  query.version = info.version;
  query.after_id = id - 1;
  query.limit = 1;
  const std::vector<storage::TreeRecord> page = store.ReadTreesPage(info.name, query);
  if (page.empty() || *page.front().id != id) {
    response.status = 404;
    Reply(response,
          Json{{"code", "NotFound"},
               {"description", "map '" + info.name + "' has no tree " + std::to_string(id)}});
    return;
  }
  const storage::TreeRecord& tree = page.front();
  std::optional<std::array<double, 2>> xy = std::array<double, 2>{tree.x, tree.y};
  if (crs84) xy = Moved(*ReprojectionOf(info.crs, kCrs84Proj), tree.x, tree.y);
  if (crs.georeferenced()) {
    SetContentCrs(response, crs84 ? kCrs84 : crs.storage_uri);
  }
  std::string feature;
  AppendFeature(feature, tree, xy);
  response.set_content(feature, kGeoJson);
}

}  // namespace

void AddOgcFeatureRoutes(httplib::Server& http, storage::MapStore& store,
                         storage::TokenStore* tokens, const std::string& scheme) {
  const auto landing = [tokens, scheme](const Request& request, Response& response) {
    if (!Authenticate(tokens, ReadPageRequest(request), response)) return;
    const std::string base = BaseUrl(request, scheme);
    Reply(response,
          Json{{"title", "ForestMap"},
               {"description", "Tree maps of this ForestMap server"},
               {"links",
                {Link(base, "self", "application/json", ""),
                 Link(base + "/api", "service-desc", "application/vnd.oai.openapi+json;version=3.0",
                      "the API definition"),
                 Link(base + "/conformance", "conformance", "application/json", ""),
                 Link(base + "/collections", "data", "application/json", "the maps")}}});
  };
  http.Get("/ogc", landing);
  http.Get("/ogc/", landing);
  http.Get("/ogc/api", [tokens, scheme](const Request& request, Response& response) {
    if (!Authenticate(tokens, ReadPageRequest(request), response)) return;
    Reply(response, OgcOpenApi(BaseUrl(request, scheme)),
          "application/vnd.oai.openapi+json;version=3.0");
  });
  http.Get("/ogc/conformance", [tokens](const Request& request, Response& response) {
    if (!Authenticate(tokens, ReadPageRequest(request), response)) return;
    Reply(response, Json{{"conformsTo",
                          {"http://www.opengis.net/spec/ogcapi-features-1/1.0/conf/core",
                           "http://www.opengis.net/spec/ogcapi-features-1/1.0/conf/geojson",
                           "http://www.opengis.net/spec/ogcapi-features-2/1.0/conf/crs"}}});
  });
  http.Get("/ogc/collections", [&store, tokens, scheme](const Request& request,
                                                        Response& response) {
    const std::optional<PageCaller> caller =
        Authenticate(tokens, ReadPageRequest(request), response);
    if (!caller) return;
    Answer(response, [&] {
      const std::string base = BaseUrl(request, scheme);
      Json collections = Json::array();
      for (const storage::MapInfo& info : store.ListMaps()) {
        if (caller->CanRead(info.name)) collections.push_back(CollectionJson(info, base));
      }
      Reply(response, Json{{"links", {Link(base + "/collections", "self", "application/json", "")}},
                           {"collections", std::move(collections)},
                           {"crs", {kCrs84}}});
    });
  });
  // NAME as in storage::ValidateMapName.
  const auto map_route = [&store, tokens, scheme](auto reply) {
    return [&store, tokens, scheme, reply](const Request& request, Response& response) {
      const std::optional<PageCaller> caller =
          Authenticate(tokens, ReadPageRequest(request), response);
      if (!caller || !MayRead(*caller, request.matches[1], response)) return;
      Answer(response, [&] {
        reply(request, response, store.GetMap(request.matches[1]), BaseUrl(request, scheme));
      });
    };
  };
  http.Get(R"(/ogc/collections/([A-Za-z0-9_.\-]+))",
           map_route([](const Request&, Response& response, const storage::MapInfo& info,
                        const std::string& base) { Reply(response, CollectionJson(info, base)); }));
  http.Get(R"(/ogc/collections/([A-Za-z0-9_.\-]+)/items)",
           map_route([&store](const Request& request, Response& response,
                              const storage::MapInfo& info, const std::string& base) {
             ReplyItems(request, response, store, info, base);
           }));
  http.Get(R"(/ogc/collections/([A-Za-z0-9_.\-]+)/items/(-?[0-9]{1,19}))",
           map_route([&store](const Request& request, Response& response,
                              const storage::MapInfo& info, const std::string&) {
             ReplyItem(request, response, store, info,
                       ParseInteger("id", request.matches[2], INT64_MIN + 1, INT64_MAX));
           }));
}

}  // namespace forestmap::server
