#include "client/io/geo_io.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>

#include "client/io/csv_columns.h"
#include "client/io/file_replace.h"
#include "client/io/geo_io_internal.h"
#include "client/io/str_cat.h"
#include "client/io/utf8.h"

namespace forestmap::client {
namespace {

using geo_internal::DatasetPtr;
using geo_internal::FeaturePtr;
using geo_internal::LastGdalError;

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

// Text that is not UTF-8 would make the upload undecodable on the server (as in CSV files).
void CheckUtf8(const std::string& text, const std::string& where) {
  const std::optional<size_t> bad = FirstInvalidUtf8(text);
  if (!bad) return;
  char byte[8];
  std::snprintf(byte, sizeof(byte), "0x%02X", static_cast<unsigned char>(text[*bad]));
  throw CsvError(StrCat({where, "not UTF-8 text (byte ", byte, " at offset ", std::to_string(*bad),
                         "); save the file as UTF-8 (a shapefile: a .cpg beside the .shp naming "
                         "its encoding, e.g. ISO-8859-1)"}));
}

// An attribute as text: a real number in FormatReal's form (as the writer decides types).
std::string AttributeText(OGRFeature& feature, int field, int64_t number, const std::string& path) {
  if (feature.GetFieldDefnRef(field)->GetType() == OFTReal) {
    return geo_internal::FormatReal(feature.GetFieldAsDouble(field));
  }
  std::string text = feature.GetFieldAsString(field);
  CheckUtf8(text, FieldWhere(path, number, feature, field));
  return text;
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
      row.attributes.emplace(name, AttributeText(feature, field, number, path));
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

bool HasPoints(OGRLayer& layer) {
  const OGRwkbGeometryType type = wkbFlatten(layer.GetGeomType());
  return type == wkbPoint || type == wkbMultiPoint;
}

std::string LayerList(GDALDataset& dataset) {
  std::string list;
  for (int i = 0; i < dataset.GetLayerCount(); ++i) {
    OGRLayer& layer = *dataset.GetLayer(i);
    list += StrCat({i ? ", " : "", layer.GetName(), " (",
                    OGRGeometryTypeToName(wkbFlatten(layer.GetGeomType())), ")"});
  }
  return list;
}

// The layer named by --layer; without it the only layer, or the only one with points (a
// GeoPackage with a boundary polygon and the trees).
OGRLayer& ChooseLayer(GDALDataset& dataset, const std::string& name, const std::string& path) {
  if (dataset.GetLayerCount() < 1) throw CsvError(path + ": no layer");
  if (!name.empty()) {
    OGRLayer* layer = dataset.GetLayerByName(name.c_str());
    if (!layer) {
      throw CsvError(
          StrCat({path, ": --layer ", name, ": no such layer (layers: ", LayerList(dataset), ")"}));
    }
    return *layer;
  }
  if (dataset.GetLayerCount() == 1) return *dataset.GetLayer(0);
  std::vector<OGRLayer*> points;
  for (int i = 0; i < dataset.GetLayerCount(); ++i) {
    if (HasPoints(*dataset.GetLayer(i))) points.push_back(dataset.GetLayer(i));
  }
  if (points.size() == 1) return *points[0];
  throw CsvError(
      StrCat({path, points.empty() ? ": no layer has points" : ": several layers have points",
              " (layers: ", LayerList(dataset), "): name the trees' layer with --layer NAME"}));
}

enum class CrsMember { kNone, kNull, kDeclared };

// A GeoJSON file's "crs" member (GeoJSON 2008): none (GDAL says WGS 84, as RFC 7946 does), null
// ("no CRS", as exports of maps without one write; GDAL still says WGS 84), or a CRS.
CrsMember GeoJsonCrsMember(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  for (size_t at = text.find("\"crs\""); at != std::string::npos;
       at = text.find("\"crs\"", at + 1)) {
    const size_t colon = text.find_first_not_of(" \t\r\n", at + 5);
    if (colon == std::string::npos || text[colon] != ':') continue;
    const size_t value = text.find_first_not_of(" \t\r\n", colon + 1);
    const bool null = value != std::string::npos && text.compare(value, 4, "null") == 0;
    return null ? CrsMember::kNull : CrsMember::kDeclared;
  }
  return CrsMember::kNone;
}

bool InLongitudeLatitude(const std::vector<MapTreeRow>& rows) {
  return std::all_of(rows.begin(), rows.end(), [](const MapTreeRow& row) {
    return std::fabs(row.x) <= 180 && std::fabs(row.y) <= 90;
  });
}

// The CRS a layer declares. None for GeoPackage's "Undefined geographic/Cartesian SRS" (srs_id
// 0, -1), for a GeoJSON file whose crs member is null, and for one without a crs member whose
// coordinates are not longitude and latitude (RFC 7946's WGS 84 is GDAL's default then; a local
// grid is no WGS 84).
std::string DeclaredCrs(GDALDataset& dataset, OGRLayer& layer, const std::string& path,
                        const std::vector<MapTreeRow>& rows) {
  return geo_internal::DeclaredLayerCrs(dataset, layer, path, InLongitudeLatitude(rows));
}

// A shapefile's attributes are in its .dbf: without it GDAL reads positions only.
void CheckShapefileParts(const std::string& path) {
  if (TreeFormatOfPath(path) != TreeFormat::kShapefile) return;
  if (!FindSidecar(path, ".dbf")) {
    throw CsvError(StrCat({path, ": no ", std::filesystem::path(path).stem().string(),
                           ".dbf beside it (the shapefile's attributes: without it the trees "
                           "would have positions only); copy it beside the .shp"}));
  }
}

}  // namespace

namespace geo_internal {

std::string DeclaredLayerCrs(GDALDataset& dataset, OGRLayer& layer, const std::string& path,
                             bool in_longitude_latitude) {
  const OGRSpatialReference* srs = layer.GetSpatialRef();
  if (!srs) return "";
  const std::string driver = dataset.GetDriver() ? dataset.GetDriver()->GetDescription() : "";
  const std::string name = srs->GetName() ? srs->GetName() : "";
  if (driver == "GPKG" && name.rfind("Undefined ", 0) == 0) return "";
  if (driver == "GeoJSON") {
    const CrsMember member = GeoJsonCrsMember(path);
    if (member == CrsMember::kNull || (member == CrsMember::kNone && !in_longitude_latitude)) {
      return "";
    }
  }
  return LayerCrs(layer);
}

}  // namespace geo_internal

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

GeoTrees ReadGeoTrees(const std::string& path, const TreeFileOptions& options) {
  geo_internal::RegisterGdal();
  if (!std::filesystem::exists(path)) throw CsvError(path + ": cannot open: no such file");
  CheckShapefileParts(path);
  CPLErrorReset();
  DatasetPtr dataset(static_cast<GDALDataset*>(
      GDALOpenEx(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, nullptr, nullptr)));
  if (!dataset) {
    throw CsvError(StrCat({path, ": not a readable ", TreeFormatName(TreeFormatOfPath(path)),
                           " file: ", LastGdalError()}));
  }
  OGRLayer& layer = ChooseLayer(*dataset, options.layer, path);
  for (int i = 0; i < layer.GetLayerDefn()->GetFieldCount(); ++i) {
    CheckUtf8(layer.GetLayerDefn()->GetFieldDefn(i)->GetNameRef(),
              StrCat({path, ": the name of field ", std::to_string(i + 1), ": "}));
  }
  const FieldColumns fields = ResolveFields(*layer.GetLayerDefn(), options, path);
  GeoTrees trees;
  for (int i = 0; i < layer.GetLayerDefn()->GetFieldCount(); ++i) {
    trees.fields.emplace_back(layer.GetLayerDefn()->GetFieldDefn(i)->GetNameRef());
  }
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
  trees.crs_wkt = DeclaredCrs(*dataset, layer, path, trees.rows);
  if (fields.dbh) {
    CheckDbhMedian(trees.rows, path, layer.GetLayerDefn()->GetFieldDefn(*fields.dbh)->GetNameRef(),
                   fields.dbh_unit);
  }
  return trees;
}

}  // namespace forestmap::client
