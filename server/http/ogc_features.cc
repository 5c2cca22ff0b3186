#include "server/http/ogc_features.h"

// clang-format off
#include "server/http/httplib_include.h"
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
#include "server/http/ogc_boundary.h"
#include "server/http/ogc_common.h"
#include "server/http/ogc_documents.h"
#include "server/http/page_auth.h"
#include "storage/staged_writes.h"

namespace forestmap::server {

using Json = nlohmann::json;

namespace {

using httplib::Request;
using httplib::Response;
using ogc::BadParameter;
using ogc::BaseUrl;
using ogc::CrsOf;
using ogc::IsCrs84;
using ogc::kCrs84;
using ogc::kCrs84Proj;
using ogc::Link;
using ogc::MapCrs;
using ogc::Moved;
using ogc::MovedBox;
using ogc::Reply;
using ogc::ReprojectionOf;
using ogc::SetContentCrs;

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
  if (info.has_boundary) {
    collection["links"].push_back(
        Link(base + "/collections/" + ogc::BoundaryCollectionId(info.name), "related",
             "application/json", info.name + ": survey boundary"));
  }
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
  if (!page.empty()) stream->order = store.ReadAttributeColumns(info.name, page_query.version);
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
  AppendFeature(feature, tree, xy, store.ReadAttributeColumns(info.name, info.version));
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
        if (!caller->CanRead(info.name)) continue;
        collections.push_back(CollectionJson(info, base));
        if (!info.has_boundary) continue;
        const storage::Boundary boundary = store.ReadBoundary(info.name, 0);
        if (!boundary.empty()) {
          collections.push_back(ogc::BoundaryCollectionJson(info, boundary, base));
        }
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
  // The survey boundary, a collection of its own (server/http/ogc_boundary.h).
  const auto boundary_route = [&store, &map_route](bool items, bool one) {
    return map_route([&store, items, one](const Request& request, Response& response,
                                          const storage::MapInfo& info, const std::string& base) {
      const storage::Boundary boundary = store.ReadBoundary(info.name, info.version);
      if (boundary.empty()) {
        throw storage::StorageError(storage::StorageError::Code::kNotFound,
                                    "map '" + info.name + "' has no survey boundary");
      }
      if (!items) return Reply(response, ogc::BoundaryCollectionJson(info, boundary, base));
      std::optional<int64_t> feature;
      if (one) feature = ParseInteger("id", request.matches[2], INT64_MIN + 1, INT64_MAX);
      ogc::ReplyBoundaryItems(request, response, info, boundary, base, feature);
    });
  };
  http.Get(R"(/ogc/collections/([A-Za-z0-9_.\-]+):boundary)", boundary_route(false, false));
  http.Get(R"(/ogc/collections/([A-Za-z0-9_.\-]+):boundary/items)", boundary_route(true, false));
  http.Get(R"(/ogc/collections/([A-Za-z0-9_.\-]+):boundary/items/(-?[0-9]{1,19}))",
           boundary_route(true, true));
}

}  // namespace forestmap::server
