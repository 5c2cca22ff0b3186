#include "server/http/ogc_documents.h"

// clang-format off
#include "server/http/httplib_include.h"
// clang-format on

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

#include "server/http/http_trees.h"
#include "server/http/ogc_features.h"

namespace forestmap::server {

using Json = nlohmann::json;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// `value` as a JSON string (bytes that are not UTF-8 become U+FFFD).
void AppendString(std::string& out, const std::string& value) {
  out += Json(value).dump(-1, ' ', false, Json::error_handler_t::replace);
}

}  // namespace

void AppendFeature(std::string& out, const storage::TreeRecord& tree,
                   const std::optional<std::array<double, 2>>& xy,
                   const std::vector<std::string>& order) {
  out += R"({"type":"Feature","id":)" + std::to_string(*tree.id) + R"(,"geometry":)";
  if (xy) {
    out += R"({"type":"Point","coordinates":[)";
    AppendJsonNumber(out, (*xy)[0]);
    out += ',';
    AppendJsonNumber(out, (*xy)[1]);
    out += "]}";
  } else {
    out += "null";
  }
  out += R"(,"properties":{"tree_id":)" + std::to_string(*tree.id) + R"(,"dbh_m":)";
  AppendJsonNumber(out, tree.dbh.value_or(kNaN));
  out += tree.status == storage::TreeStatus::kConfirmed ? R"(,"status":"confirmed")"
                                                        : R"(,"status":"candidate")";
  out += R"(,"observations":)" + std::to_string(tree.observations);
  const auto append_name = [&out](const std::string& name) {
    std::string lower = name;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    const bool ours =
        lower == "tree_id" || lower == "dbh_m" || lower == "status" || lower == "observations";
    out += ',';
    AppendString(out, ours ? "survey_" + name : name);
    out += ':';
  };
  const auto append = [&](const std::string& name) {
    if (const auto it = tree.attributes.find(name); it != tree.attributes.end()) {
      append_name(name);
      AppendString(out, it->second);
    } else if (tree.null_attributes.count(name) != 0) {
      append_name(name);
      out += "null";
    }
  };
  for (const std::string& name : order) append(name);
  const auto ordered = [&order](const std::string& name) {
    return std::find(order.begin(), order.end(), name) != order.end();
  };
  for (const auto& [name, value] : tree.attributes) {
    if (!ordered(name)) append(name);
  }
  for (const std::string& name : tree.null_attributes) {
    if (!ordered(name)) append(name);
  }
  out += "}}";
}

bool ItemsStream::Write(httplib::DataSink& sink) {
  text_.clear();
  if (next_ == 0) text_ = head;
  const size_t end = std::min(trees.size(), next_ + kFeaturesPerChunk);
  for (; next_ < end; ++next_) {
    if (next_ > 0) text_ += ',';
    AppendFeature(text_, trees[next_], xy[next_], order);
  }
  const bool last = next_ == trees.size();
  if (last) text_ += "]}";
  if (!sink.write(text_.data(), text_.size())) return false;
  if (last) sink.done();
  return true;
}

// Clients read it for the parameters and the largest page (GDAL's OAPIF driver sizes its pages
// from `limit`'s maximum).
nlohmann::json OgcOpenApi(const std::string& base) {
  const auto param = [](const char* name, const char* in, Json schema, const char* about) {
    return Json{{"name", name},
                {"in", in},
                {"required", std::string(in) == "path"},
                {"schema", std::move(schema)},
                {"description", about}};
  };
  const Json collection = param("collectionId", "path", {{"type", "string"}}, "a map's name");
  const Json crs = param("crs", "query", {{"type", "string"}, {"format", "uri"}},
                         "the answer's CRS: CRS84 (default) or the map's storageCrs");
  const auto get = [](const char* summary, Json parameters, const char* type) {
    return Json{{"get",
                 {{"summary", summary},
                  {"parameters", std::move(parameters)},
                  {"responses",
                   {{"200", {{"description", summary}, {"content", {{type, Json::object()}}}}}}}}}};
  };
  return {{"openapi", "3.0.3"},
          {"info", {{"title", "ForestMap OGC API - Features"}, {"version", "1.0.0"}}},
          {"servers", {{{"url", base}}}},
          {"paths",
           {{"/", get("landing page", Json::array(), "application/json")},
            {"/conformance", get("conformance classes", Json::array(), "application/json")},
            {"/collections", get("the maps", Json::array(), "application/json")},
            {"/collections/{collectionId}", get("one map", {collection}, "application/json")},
            {"/collections/{collectionId}/items",
             get("a map's trees",
                 {collection,
                  param("limit", "query",
                        {{"type", "integer"},
                         {"minimum", 1},
                         {"maximum", kOgcMaxLimit},
                         {"default", kOgcDefaultLimit}},
                        "trees per page"),
                  param("bbox", "query",
                        {{"type", "array"},
                         {"items", {{"type", "number"}}},
                         {"minItems", 4},
                         {"maxItems", 4}},
                        "minx,miny,maxx,maxy in bbox-crs"),
                  param("bbox-crs", "query", {{"type", "string"}, {"format", "uri"}},
                        "the bbox's CRS: CRS84 (default) or the map's storageCrs"),
                  crs},
                 kGeoJson)},
            {"/collections/{collectionId}/items/{featureId}",
             get("one tree",
                 {collection, param("featureId", "path", {{"type", "integer"}}, "tree id"), crs},
                 kGeoJson)}}}};
}

}  // namespace forestmap::server
