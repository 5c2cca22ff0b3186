#include "client/io/geo_io.h"

#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>

#include "client/io/csv_columns.h"
#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

constexpr const char* kLayerName = "trees";
constexpr const char* kTreeFields[] = {"id", "x", "y", "z", "dbh"};

void RegisterGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(CPLQuietErrorHandler);  // errors are read and reported by us
  });
}

std::string LastGdalError() {
  const std::string message = CPLGetLastErrorMsg();
  return message.empty() ? "unknown GDAL error" : message;
}

const char* DriverName(TreeFormat format) {
  switch (format) {
    case TreeFormat::kGeoJson:
      return "GeoJSON";
    case TreeFormat::kGeoPackage:
      return "GPKG";
    case TreeFormat::kShapefile:
      return "ESRI Shapefile";
    default:
      return "CSV";
  }
}

struct DatasetCloser {
  void operator()(GDALDataset* dataset) const { GDALClose(dataset); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

struct FeatureDeleter {
  void operator()(OGRFeature* feature) const { OGRFeature::DestroyFeature(feature); }
};
using FeaturePtr = std::unique_ptr<OGRFeature, FeatureDeleter>;

void CreateFields(OGRLayer& layer, const std::vector<ExportedAttribute>& attributes,
                  const std::string& path) {
  std::vector<std::pair<std::string, OGRFieldType>> fields = {
      {"id", OFTInteger64}, {"x", OFTReal}, {"y", OFTReal}, {"z", OFTReal}, {"dbh", OFTReal}};
  for (const ExportedAttribute& attribute : attributes) {
    fields.emplace_back(attribute.column, OFTString);
  }
  for (const auto& [name, type] : fields) {
    OGRFieldDefn field(name.c_str(), type);
    if (layer.CreateField(&field) != OGRERR_NONE) {
      throw CsvError(path + ": cannot create field '" + name + "': " + LastGdalError());
    }
  }
}

// Attribute i is field kTreeFieldCount + i (shapefiles cut names to 10 characters, so fields
// are addressed by position, not name).
constexpr int kTreeFieldCount = static_cast<int>(std::size(kTreeFields));

void WriteFeature(OGRLayer& layer, const MapTreeRow& row,
                  const std::vector<ExportedAttribute>& names, size_t index,
                  const std::string& path) {
  FeaturePtr feature(OGRFeature::CreateFeature(layer.GetLayerDefn()));
  if (row.id) feature->SetField(0, static_cast<GIntBig>(*row.id));
  feature->SetField(1, row.x);
  feature->SetField(2, row.y);
  if (row.z) feature->SetField(3, *row.z);
  if (row.dbh) feature->SetField(4, *row.dbh);
  for (int i = 0; i < kTreeFieldCount; ++i) {
    if (!feature->IsFieldSet(i)) feature->SetFieldNull(i);
  }
  for (size_t i = 0; i < names.size(); ++i) {
    const int field = kTreeFieldCount + static_cast<int>(i);
    const auto it = row.attributes.find(names[i].name);
    if (it == row.attributes.end()) {
      feature->SetFieldNull(field);
    } else {
      feature->SetField(field, it->second.c_str());
    }
  }
  OGRPoint point(row.x, row.y);
  feature->SetGeometry(&point);
  if (layer.CreateFeature(feature.get()) != OGRERR_NONE) {
    throw CsvError(path + ": cannot write tree " + std::to_string(index + 1) + ": " +
                   LastGdalError());
  }
}

// The spatial reference of `crs` (EPSG:n, WKT or PROJ string), x = easting, y = northing.
std::unique_ptr<OGRSpatialReference> SpatialReference(const std::string& crs,
                                                      const std::string& path) {
  auto srs = std::make_unique<OGRSpatialReference>();
  if (srs->SetFromUserInput(crs.c_str()) != OGRERR_NONE) {
    throw CsvError(path + ": the map's CRS '" + crs.substr(0, 64) + "' is unknown to GDAL");
  }
  srs->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

void WriteLayer(GDALDataset& dataset, const std::vector<MapTreeRow>& rows, OGRSpatialReference* srs,
                const std::string& path) {
  const std::vector<ExportedAttribute> names = ExportedAttributes(rows);
  OGRLayer* layer = dataset.CreateLayer(kLayerName, srs, wkbPoint, nullptr);
  if (!layer) throw CsvError(path + ": cannot create a layer: " + LastGdalError());
  CreateFields(*layer, names, path);
  // One transaction (GeoPackage): thousands of features commit at once.
  const bool transaction = dataset.StartTransaction() == OGRERR_NONE;
  for (size_t i = 0; i < rows.size(); ++i) WriteFeature(*layer, rows[i], names, i, path);
  if (transaction && dataset.CommitTransaction() != OGRERR_NONE) {
    throw CsvError(path + ": cannot commit: " + LastGdalError());
  }
}

// Where the tree fields of a layer are; x and y come from the point unless named by --columns.
struct FieldColumns {
  std::optional<int> id, x, y, z, dbh;
  std::optional<int> dbh_fallback;  // read where dbh is unknown (TreeLoc++)
  std::vector<int> attributes;
  DbhUnit dbh_unit = DbhUnit::kMetre;
  bool point_z = true;  // the point geometry's z is the stem base (not for lidR tree tops)
};

FieldColumns ResolveFields(const OGRFeatureDefn& definition, const TreeFileOptions& options,
                           const std::string& path) {
  std::vector<std::string> names;
  for (int i = 0; i < definition.GetFieldCount(); ++i) {
    names.emplace_back(definition.GetFieldDefn(i)->GetNameRef());
  }
  const ResolvedColumns resolved = ResolveMapColumns(names, options, path);
  FieldColumns fields;
  fields.dbh_unit = resolved.dbh_unit;
  if (resolved.dbh_fallback) fields.dbh_fallback = static_cast<int>(*resolved.dbh_fallback);
  fields.point_z = !resolved.z_is_tree_height;
  for (int i = 0; i < static_cast<int>(names.size()); ++i) {
    const std::string& canonical = resolved.canonical[i];
    if (canonical == "id")
      fields.id = i;
    else if (canonical == "z")
      fields.z = i;
    else if (canonical == "dbh")
      fields.dbh = i;
    else if (canonical == "x")
      fields.x = options.columns.count("x") ? std::optional(i) : std::nullopt;
    else if (canonical == "y")
      fields.y = options.columns.count("y") ? std::optional(i) : std::nullopt;
    else
      fields.attributes.push_back(i);
  }
  return fields;
}

// A numeric field: null, unset, empty or NA is unknown; text must be a finite number.
std::optional<double> FieldNumber(OGRFeature& feature, int field, const std::string& where) {
  if (!feature.IsFieldSetAndNotNull(field)) return std::nullopt;
  const OGRFieldType type = feature.GetFieldDefnRef(field)->GetType();
  double value = 0;
  if (type == OFTReal || type == OFTInteger || type == OFTInteger64) {
    value = feature.GetFieldAsDouble(field);
  } else {
    const std::string text(Trim(feature.GetFieldAsString(field)));
    if (text.empty() || text == "NA" || text == "NaN") return std::nullopt;
    char* end = nullptr;
    value = std::strtod(text.c_str(), &end);
    if (end != text.c_str() + text.size()) {
      throw CsvError(where + "'" + text + "' is not a number");
    }
  }
  if (!std::isfinite(value)) throw CsvError(where + "is not a finite number");
  return value;
}

std::string FieldWhere(const std::string& path, int64_t feature, OGRFeature& f, int field) {
  return StrCat({path, ": feature ", std::to_string(feature), ": field '",
                 f.GetFieldDefnRef(field)->GetNameRef(), "': "});
}

MapTreeRow ReadFeature(OGRFeature& feature, const FieldColumns& fields, int64_t number,
                       const std::string& path) {
  MapTreeRow row;
  const auto number_of = [&](const std::optional<int>& field) -> std::optional<double> {
    if (!field) return std::nullopt;
    return FieldNumber(feature, *field, FieldWhere(path, number, feature, *field));
  };
  const OGRGeometry* geometry = feature.GetGeometryRef();
  const bool point =
      geometry && wkbFlatten(geometry->getGeometryType()) == wkbPoint && !geometry->IsEmpty();
  if (fields.x && fields.y) {
    const std::optional<double> x = number_of(fields.x), y = number_of(fields.y);
    if (!x || !y)
      throw CsvError(FieldWhere(path, number, feature, *(x ? fields.y : fields.x)) +
                     "missing value (required)");
    row.x = *x;
    row.y = *y;
  } else if (point) {
    const OGRPoint& p = *geometry->toPoint();
    row.x = p.getX();
    row.y = p.getY();
    if (fields.point_z && p.Is3D() && std::isfinite(p.getZ())) row.z = p.getZ();
  } else {
    throw CsvError(StrCat({path, ": feature ", std::to_string(number),
                           ": no point geometry (trees are points; or name x and y fields with "
                           "--columns)"}));
  }
  if (const std::optional<double> z = number_of(fields.z)) row.z = z;
  row.dbh = number_of(fields.dbh);
  const std::optional<int> dbh_field = row.dbh ? fields.dbh : fields.dbh_fallback;
  if (!row.dbh) row.dbh = number_of(fields.dbh_fallback);
  if (row.dbh && *row.dbh < 0) {
    throw CsvError(FieldWhere(path, number, feature, *dbh_field) + "is negative");
  }
  if (row.dbh) *row.dbh *= MetresPer(fields.dbh_unit);
  if (const std::optional<double> id = number_of(fields.id)) {
    if (*id != std::floor(*id)) {
      throw CsvError(FieldWhere(path, number, feature, *fields.id) + "is not an integer");
    }
    row.id = static_cast<int64_t>(*id);
  }
  for (int field : fields.attributes) {
    const char* name = feature.GetFieldDefnRef(field)->GetNameRef();
    if (feature.IsFieldSetAndNotNull(field)) {
      row.attributes.emplace(name, feature.GetFieldAsString(field));
    } else {
      row.null_attributes.insert(name);  // the layer has the field; this feature no value
    }
  }
  return row;
}

std::string LayerCrs(OGRLayer& layer) {
  const OGRSpatialReference* srs = layer.GetSpatialRef();
  if (!srs) return "";
  char* wkt = nullptr;
  const char* options[] = {"FORMAT=WKT2_2019", nullptr};
  srs->exportToWkt(&wkt, options);
  std::string text = wkt ? wkt : "";
  CPLFree(wkt);
  return text;
}

}  // namespace

TreeFormat ParseTreeFormat(const std::string& name) {
  if (name == "csv") return TreeFormat::kCsv;
  if (name == "geojson") return TreeFormat::kGeoJson;
  if (name == "gpkg") return TreeFormat::kGeoPackage;
  if (name == "shp") return TreeFormat::kShapefile;
  throw std::invalid_argument("--format: '" + name + "' is not one of csv, geojson, gpkg, shp");
}

TreeFormat TreeFormatOfPath(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".geojson" || extension == ".json") return TreeFormat::kGeoJson;
  if (extension == ".gpkg") return TreeFormat::kGeoPackage;
  if (extension == ".shp") return TreeFormat::kShapefile;
  return TreeFormat::kCsv;
}

const char* TreeFormatName(TreeFormat format) {
  switch (format) {
    case TreeFormat::kGeoJson:
      return "geojson";
    case TreeFormat::kGeoPackage:
      return "gpkg";
    case TreeFormat::kShapefile:
      return "shp";
    default:
      return "csv";
  }
}

}  // namespace forestmap::client

namespace forestmap::client {

void WriteGeoTrees(const std::string& path, TreeFormat format, const std::vector<MapTreeRow>& rows,
                   const std::string& crs) {
  RegisterGdal();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(DriverName(format));
  if (!driver || format == TreeFormat::kCsv) {
    throw CsvError(path + ": GDAL has no " + TreeFormatName(format) + " writer");
  }
  std::unique_ptr<OGRSpatialReference> srs;
  if (!crs.empty()) srs = SpatialReference(crs, path);
  if (std::filesystem::exists(path)) driver->QuietDelete(path.c_str());
  CPLErrorReset();
  DatasetPtr dataset(driver->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  if (!dataset) throw CsvError(path + ": cannot create: " + LastGdalError());
  try {
    WriteLayer(*dataset, rows, srs.get(), path);
    dataset->FlushCache();
  } catch (...) {
    dataset.reset();
    driver->QuietDelete(path.c_str());  // nothing half-written stays behind
    throw;
  }
  dataset.reset();
  if (CPLGetLastErrorType() == CE_Failure) {
    const std::string error = LastGdalError();
    driver->QuietDelete(path.c_str());
    throw CsvError(path + ": " + error);
  }
}

}  // namespace forestmap::client

namespace forestmap::client {

GeoTrees ReadGeoTrees(const std::string& path, const TreeFileOptions& options) {
  RegisterGdal();
  if (!std::filesystem::exists(path)) throw CsvError(path + ": cannot open: no such file");
  CPLErrorReset();
  DatasetPtr dataset(static_cast<GDALDataset*>(
      GDALOpenEx(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, nullptr, nullptr)));
  if (!dataset) {
    throw CsvError(StrCat({path, ": not a readable ", TreeFormatName(TreeFormatOfPath(path)),
                           " file: ", LastGdalError()}));
  }
  if (dataset->GetLayerCount() < 1) throw CsvError(path + ": no layer");
  OGRLayer& layer = *dataset->GetLayer(0);
  const FieldColumns fields = ResolveFields(*layer.GetLayerDefn(), options, path);
  GeoTrees trees;
  trees.crs_wkt = LayerCrs(layer);
  std::map<int64_t, int64_t> feature_of_id;
  layer.ResetReading();
  int64_t number = 0;
  while (FeaturePtr feature{layer.GetNextFeature()}) {
    ++number;
    trees.rows.push_back(ReadFeature(*feature, fields, number, path));
    const std::optional<int64_t> id = trees.rows.back().id;
    if (id && !feature_of_id.emplace(*id, number).second) {
      throw CsvError(StrCat({path, ": feature ", std::to_string(number), ": duplicate tree id ",
                             std::to_string(*id), " (also feature ",
                             std::to_string(feature_of_id[*id]), ")"}));
    }
  }
  if (CPLGetLastErrorType() == CE_Failure) throw CsvError(path + ": " + LastGdalError());
  if (fields.dbh) {
    CheckDbhMedian(trees.rows, path, layer.GetLayerDefn()->GetFieldDefn(*fields.dbh)->GetNameRef(),
                   fields.dbh_unit);
  }
  return trees;
}

}  // namespace forestmap::client
