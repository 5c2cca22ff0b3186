#include "server/http/http_page.h"

// Eigen (through http_page.h) before httplib.h: httplib pulls in <resolv.h>, whose `_res` macro
// breaks Eigen's headers when they come after it.
#include "server/http/http_route.h"
#include "server/http/http_trees.h"
#include "server/http/ogc_features.h"
#include "server/http/page_auth.h"
// clang-format off
#include "server/http/httplib_include.h"
// clang-format on

#include <algorithm>
#include <deque>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

namespace forestmap::server {

using Json = nlohmann::json;

namespace {

Json MapJson(const storage::MapInfo& info) {
  Json map = {{"name", info.name},
              {"trees", info.tree_count},
              {"version", info.version},
              {"crs", info.crs.size() <= 32 ? info.crs : "WKT"}};
  if (info.extent) {
    map["extent"] = {info.extent->min_x, info.extent->min_y, info.extent->max_x,
                     info.extent->max_y};
  }
  return map;
}

void Reply(httplib::Response& response, const Json& body) {
  response.set_content(body.dump(), "application/json");
}

// Runs `body`, turning a store error (unknown map, ...) into a 404 with its message.
template <typename Body>
void Guarded(httplib::Response& response, Body body) {
  try {
    body();
  } catch (const std::exception& e) {
    response.status = 404;
    Reply(response, Json{{"error", e.what()}});
  }
}

// The page's names of a version's kind and of a relocalization's status: its own, so that the
// page reads the same whatever the gRPC API calls them.
const char* KindName(storage::VersionKind kind) {
  using Kind = storage::VersionKind;
  switch (kind) {
    case Kind::kCreate:
      return "CREATE";
    case Kind::kUpload:
      return "UPLOAD";
    case Kind::kReplace:
      return "REPLACE";
    case Kind::kObserve:
      return "OBSERVE";
    case Kind::kRestore:
      return "RESTORE";
    case Kind::kRemoveSource:
      return "REMOVE_SOURCE";
    case Kind::kMigrated:
      return "MIGRATED";
  }
  return "KIND_UNSPECIFIED";
}

const char* StatusName(algorithms::RelocalizeStatus status) {
  switch (status) {
    case algorithms::RelocalizeStatus::kLocalized:
      return "LOCALIZED";
    case algorithms::RelocalizeStatus::kAmbiguous:
      return "AMBIGUOUS";
    case algorithms::RelocalizeStatus::kNotFound:
      return "NOT_FOUND";
  }
  return "STATUS_UNSPECIFIED";
}

Json VersionsJson(const std::vector<storage::VersionRecord>& records) {
  Json versions = Json::array();
  for (const storage::VersionRecord& v : records) {
    versions.push_back({{"version", v.version},
                        {"kind", KindName(v.kind)},
                        {"source", v.source},
                        {"trees", v.tree_count},
                        {"time_ms", v.created_unix_ms}});
  }
  return versions;
}

Json AnswersJson(const RecentAnswers& answers, const PageCaller& caller) {
  Json list = Json::array();
  for (const RecentAnswer& a : answers.Get()) {
    if (!caller.CanRead(a.map_name)) continue;
    Json item = {{"map", a.map_name},
                 {"time_ms", a.unix_ms},
                 {"status", StatusName(a.status)},
                 {"inliers", a.inliers}};
    if (a.position) {
      item["x"] = a.position->x();
      item["y"] = a.position->y();
    }
    if (a.geodetic) {
      item["lat"] = a.geodetic->latitude_deg;
      item["lon"] = a.geodetic->longitude_deg;
    }
    list.push_back(item);
  }
  return list;
}

// The densities of the last few map versions the page asked for (a version never changes).
class DensityCache {
 public:
  std::shared_ptr<const TreeDensity> Of(storage::MapStore& store, const storage::MapInfo& info) {
    const Key key{info.name, info.version, info.created_unix_ms};
    {
      const std::lock_guard lock(mutex_);
      for (const auto& [k, density] : kept_) {
        if (k == key) return density;
      }
    }
    auto density = std::make_shared<const TreeDensity>(DensityOf(store, info));
    const std::lock_guard lock(mutex_);
    kept_.emplace_back(key, density);
    if (kept_.size() > kKept) kept_.pop_front();
    return density;
  }

 private:
  using Key = std::tuple<std::string, int64_t, int64_t>;  // name, version, created_unix_ms
  static constexpr size_t kKept = 8;                      // 256 KiB each at most
  std::mutex mutex_;
  std::deque<std::pair<Key, std::shared_ptr<const TreeDensity>>> kept_;
};

// A survey boundary (map frame): polygons, each its outer ring and then its holes, of [x, y].
Json BoundaryJson(const storage::Boundary& boundary) {
  Json polygons = Json::array();
  for (const storage::BoundaryPolygon& polygon : boundary) {
    Json rings = Json::array();
    for (size_t r = 0; r <= polygon.holes.size(); ++r) {
      Json ring = Json::array();
      for (const storage::BoundaryPoint& p : r == 0 ? polygon.outer : polygon.holes[r - 1]) {
        ring.push_back({p.x, p.y});
      }
      rings.push_back(std::move(ring));
    }
    polygons.push_back(std::move(rings));
  }
  return polygons;
}

// Answers `request` (read by ReadPageRequest) for `caller`; `secure`: over HTTPS.
void Answer(storage::MapStore& store, const RecentAnswers& answers, DensityCache& densities,
            const httplib::Request& http_request, const PageRequest& request,
            const PageCaller& caller, bool secure, httplib::Response& response) {
  switch (request.route) {
    case PageRoute::kPage:
      if (caller.token && request.has_token_param) {
        // A browser's first visit, /?token=...: the token moves into a cookie that scripts
        // cannot read and other sites cannot send, and the page reloads without it in its
        // address (and so in the history); the fragment (#map=...) stays. Only the token that
        // was checked becomes the cookie.
        if (request.token_in_query) {
          response.set_header("Set-Cookie", std::string(kTokenCookie) + "=" + request.token +
                                                "; Path=/; HttpOnly; SameSite=Strict" +
                                                (secure ? "; Secure" : ""));
        }
        response.set_redirect("/", 303);
        return;
      }
      response.set_content(kHttpPageHtml, "text/html; charset=utf-8");
      return;
    case PageRoute::kMaps:
      Guarded(response, [&] {
        Json maps = Json::array();
        for (const storage::MapInfo& info : store.ListMaps()) {
          if (caller.CanRead(info.name)) maps.push_back(MapJson(info));
        }
        Reply(response, maps);
      });
      return;
    case PageRoute::kTrees: {
      if (!MayRead(caller, request.map, response)) return;
      std::optional<storage::Extent> box;
      try {
        if (http_request.has_param("bbox")) {
          box = ParseBox("bbox", http_request.get_param_value("bbox"));
        }
      } catch (const std::invalid_argument& e) {
        response.status = 400;
        return Reply(response, Json{{"error", e.what()}});
      }
      Guarded(response, [&] {
        const storage::MapInfo info = store.GetMap(request.map);
        ReplyTreesStreamed(response, store, info, MapJson(info).dump(), box);
      });
      return;
    }
    case PageRoute::kDensity:
      if (!MayRead(caller, request.map, response)) return;
      Guarded(response, [&] {
        const storage::MapInfo info = store.GetMap(request.map);
        const std::shared_ptr<const TreeDensity> d = densities.Of(store, info);
        Reply(response, Json{{"map", MapJson(info)},
                             {"min_x", d->min_x},
                             {"min_y", d->min_y},
                             {"cell_m", d->cell_m},
                             {"columns", d->columns},
                             {"rows", d->rows},
                             {"counts", d->counts}});
      });
      return;
    case PageRoute::kVersions:
      if (!MayRead(caller, request.map, response)) return;
      Guarded(response, [&] { Reply(response, VersionsJson(store.ListVersions(request.map, 0))); });
      return;
    case PageRoute::kBoundary:
      if (!MayRead(caller, request.map, response)) return;
      Guarded(response, [&] {
        Reply(response, Json{{"polygons", BoundaryJson(store.ReadBoundary(request.map, 0))}});
      });
      return;
    case PageRoute::kRelocalizations:
      Reply(response, AnswersJson(answers, caller));
      return;
    case PageRoute::kNotFound:
      break;
  }
  response.status = 404;
  Reply(response, Json{{"error", "no such page"}});
}

void AddPageRoutes(httplib::Server& http, storage::MapStore& store, const RecentAnswers& answers,
                   storage::TokenStore* tokens, bool secure) {
  // OGC API - Features under /ogc first: cpp-httplib takes the first route that matches.
  AddOgcFeatureRoutes(http, store, tokens, secure ? "https" : "http");
  // Every other GET path to one handler: the route is RoutePage's (http_route.h). [\s\S]: any
  // byte, newlines of a decoded path included.
  auto densities = std::make_shared<DensityCache>();
  http.Get(R"([\s\S]*)", [&store, &answers, tokens, secure, densities](
                             const httplib::Request& request, httplib::Response& response) {
    const PageRequest read = ReadPageRequest(request);
    const std::optional<PageCaller> caller = Authenticate(tokens, read, response);
    if (caller) Answer(store, answers, *densities, request, read, *caller, secure, response);
  });
}

}  // namespace

HttpPage::HttpPage(storage::MapStore& store, const RecentAnswers& answers,
                   const std::string& address, storage::TokenStore* tokens, const HttpsSetup& https)
    : listener_("--http", address, https, [&](httplib::Server& http) {
        AddPageRoutes(http, store, answers, tokens, static_cast<bool>(https));
      }) {}

}  // namespace forestmap::server
