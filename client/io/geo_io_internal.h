#pragma once
// GDAL handles and helpers shared by geo_io.cc (reading) and geo_write.cc (writing): the only
// files that include GDAL.

#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "client/io/geo_io.h"

namespace forestmap::client::geo_internal {

inline void RegisterGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(CPLQuietErrorHandler);  // errors are read and reported by us
  });
}

inline std::string LastGdalError() {
  const std::string message = CPLGetLastErrorMsg();
  return message.empty() ? "unknown GDAL error" : message;
}

struct DatasetCloser {
  void operator()(GDALDataset* dataset) const { GDALClose(dataset); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

struct FeatureDeleter {
  void operator()(OGRFeature* feature) const { OGRFeature::DestroyFeature(feature); }
};
using FeaturePtr = std::unique_ptr<OGRFeature, FeatureDeleter>;

// A real attribute's text: 15 significant digits ("14.9", "62"), or 17 where 15 do not read back
// as the same double. The writer exports an attribute as Real only when its text is this form.
inline std::string FormatReal(double value) {
  char text[40];
  std::snprintf(text, sizeof(text), "%.15g", value);
  if (std::strtod(text, nullptr) != value) std::snprintf(text, sizeof(text), "%.17g", value);
  return text;
}

// A layer to create: its name, the file's format and its CRS (null: none).
struct LayerSpec {
  std::string name;
  TreeFormat format;
  OGRSpatialReference* srs;  // GDAL 3.6 takes it non-const
};

// Creates the layer with the format's options (shapefiles: UTF-8; GeoJSON in WGS 84: RFC 7946).
OGRLayer& CreateLayer(GDALDataset& dataset, const LayerSpec& spec, OGRwkbGeometryType type,
                      const std::string& path);

// Writes the GIS file `path` as WriteGeoTrees does (geo_io.h: a temporary file renamed into place,
// a GeoPackage's other layers kept, no CRS said as such), its layer written by `write_layer`,
// which returns warnings for the user.
using LayerWriter =
    std::function<std::vector<std::string>(GDALDataset& dataset, const LayerSpec& spec)>;
std::vector<std::string> WriteGeoFile(const std::string& path, TreeFormat format,
                                      const std::string& crs, const std::string& layer,
                                      const LayerWriter& write_layer);

// The CRS a layer declares, as WKT: none for GeoPackage's "Undefined geographic/Cartesian SRS"
// (srs_id 0, -1), for a GeoJSON file whose crs member is null, and for one without a crs member
// whose coordinates are not `in_longitude_latitude` (RFC 7946's WGS 84 is GDAL's default then; a
// local grid is no WGS 84).
std::string DeclaredLayerCrs(GDALDataset& dataset, OGRLayer& layer, const std::string& path,
                             bool in_longitude_latitude);

}  // namespace forestmap::client::geo_internal
