#pragma once
// The documents of OGC API - Features (server/http/ogc_features.h) that do not depend on a
// request: GeoJSON features written as text, an items answer streamed in chunks, and the API
// definition.

#include <array>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"

namespace httplib {
class DataSink;
}  // namespace httplib

namespace forestmap::server {

inline constexpr const char* kGeoJson = "application/geo+json";

// A tree as a GeoJSON feature at `xy` (null geometry: off the CRS's domain):
// {tree_id, dbh_m, status, observations} and the survey's attributes, a survey column named like
// one of ours (in any case: GIS formats ignore it) renamed survey_<name>, those named in `order`
// (the map's attribute column order) first, in that order, then the others by name. Bytes of an
// attribute that are not UTF-8 become U+FFFD.
void AppendFeature(std::string& out, const storage::TreeRecord& tree,
                   const std::optional<std::array<double, 2>>& xy,
                   const std::vector<std::string>& order = {});

// An items answer written in chunks of kFeaturesPerChunk features, so that a request never holds
// more text than one chunk (whole pages of 10,000 features kept ~10 MB in each HTTP thread's
// malloc arena).
struct ItemsStream {
  static constexpr size_t kFeaturesPerChunk = 256;
  std::string head;  // up to and including "features":[
  std::vector<storage::TreeRecord> trees;
  std::vector<std::optional<std::array<double, 2>>> xy;  // per tree, as AppendFeature takes it
  std::vector<std::string> order;                        // of the attributes, as AppendFeature

  // Writes the next chunk to `sink`; false: the client left.
  bool Write(httplib::DataSink& sink);

 private:
  size_t next_ = 0;
  std::string text_;
};

// The API definition (OpenAPI 3.0) of the routes, served at `base`.
nlohmann::json OgcOpenApi(const std::string& base);

}  // namespace forestmap::server
