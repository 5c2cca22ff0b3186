// WriteGeoTrees (geo_io.h): typed fields, the layer, and putting the files in place atomically.

#include <cerrno>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <system_error>

#include "client/io/file_replace.h"
#include "client/io/geo_io.h"
#include "client/io/geo_io_internal.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;
using geo_internal::DatasetPtr;
using geo_internal::FeaturePtr;
using geo_internal::FormatReal;
using geo_internal::LastGdalError;
using geo_internal::LayerSpec;

constexpr int kTreeFieldCount = 5;  // id, x, y, z, dbh; attribute i is field kTreeFieldCount + i
// A shapefile's Real field is written "%24.15f": 15 decimals, 8 digits before the point.
constexpr double kShapefileRealLimit = 1e8;
// GeoPackage's own columns (the feature id and the geometry): attributes so named are renamed.
const std::set<std::string> kGeoReserved = {"fid", "geom", "geometry", "ogc_fid"};
// A shapefile's files; those of an earlier export that this one does not write are removed.
const std::vector<std::string> kShapefileParts = {".shp", ".shx", ".dbf", ".prj",
                                                  ".cpg", ".qix", ".sbn", ".sbx"};

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

bool IsInteger(const std::string& text) {
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  const long long value = std::strtoll(text.c_str(), &end, 10);
  return errno == 0 && end == text.c_str() + text.size() && std::to_string(value) == text;
}

// A number every format can hold in a Real field: 15 significant digits at most (GDAL's GeoJSON
// writer keeps no more) and below a shapefile's 8 digits before the point.
bool IsReal(const std::string& text) {
  if (text.empty()) return false;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  char shortest[40];
  std::snprintf(shortest, sizeof(shortest), "%.15g", value);
  return end == text.c_str() + text.size() && std::isfinite(value) && shortest == text &&
         std::strtod(shortest, nullptr) == value && std::fabs(value) < kShapefileRealLimit;
}

// Whether a shapefile's 15 fixed decimals hold `text` (a Real) as written: 4.29e-16 becomes 0.
bool ShapefileHolds(const std::string& text) {
  const double value = std::strtod(text.c_str(), nullptr);
  char fixed[64];
  std::snprintf(fixed, sizeof(fixed), "%.15f", value);
  return std::strtod(fixed, nullptr) == value;
}

// Integer64 when every value of the attribute is an integer, Real when every one is a number
// (IsReal), else String (and String when no row has a value): the same in every format, so a
// column has one type in all of them.
OGRFieldType AttributeType(const std::vector<MapTreeRow>& rows, const std::string& name) {
  bool integer = true, real = true, any = false;
  for (const MapTreeRow& row : rows) {
    const auto it = row.attributes.find(name);
    if (it == row.attributes.end()) continue;
    any = true;
    integer = integer && IsInteger(it->second);
    real = real && IsReal(it->second);
    if (!integer && !real) return OFTString;
  }
  if (!any) return OFTString;
  return integer ? OFTInteger64 : OFTReal;
}

struct Column {
  ExportedAttribute attribute;
  OGRFieldType type = OFTString;
};

// Creates the fields; returns a warning per field the driver renamed (shapefiles: 10 characters).
std::vector<std::string> CreateFields(OGRLayer& layer, const std::vector<Column>& columns,
                                      const std::string& path) {
  std::vector<std::pair<std::string, OGRFieldType>> fields = {
      {"id", OFTInteger64}, {"x", OFTReal}, {"y", OFTReal}, {"z", OFTReal}, {"dbh", OFTReal}};
  for (const Column& column : columns) fields.emplace_back(column.attribute.column, column.type);
  std::vector<std::string> warnings;
  for (const auto& [name, type] : fields) {
    OGRFieldDefn field(name.c_str(), type);
    if (layer.CreateField(&field) != OGRERR_NONE) {
      throw CsvError(path + ": cannot create field '" + name + "': " + LastGdalError());
    }
    const OGRFeatureDefn& definition = *layer.GetLayerDefn();
    const std::string written =
        definition.GetFieldDefn(definition.GetFieldCount() - 1)->GetNameRef();
    if (written != name) {
      warnings.push_back(path + ": field '" + name + "' is written as '" + written + "'");
    }
  }
  return warnings;
}

void SetAttribute(OGRFeature& feature, int field, const std::string& text, OGRFieldType type) {
  if (type == OFTInteger64) {
    feature.SetField(field, static_cast<GIntBig>(std::strtoll(text.c_str(), nullptr, 10)));
  } else if (type == OFTReal) {
    feature.SetField(field, std::strtod(text.c_str(), nullptr));
  } else {
    feature.SetField(field, text.c_str());
  }
}

void WriteFeature(OGRLayer& layer, const MapTreeRow& row, const std::vector<Column>& columns,
                  size_t index, const std::string& path) {
  FeaturePtr feature(OGRFeature::CreateFeature(layer.GetLayerDefn()));
  if (row.id) feature->SetField(0, static_cast<GIntBig>(*row.id));
  feature->SetField(1, row.x);
  feature->SetField(2, row.y);
  if (row.z) feature->SetField(3, *row.z);
  if (row.dbh) feature->SetField(4, *row.dbh);
  for (int i = 0; i < kTreeFieldCount; ++i) {
    if (!feature->IsFieldSet(i)) feature->SetFieldNull(i);
  }
  for (size_t i = 0; i < columns.size(); ++i) {
    const int field = kTreeFieldCount + static_cast<int>(i);
    const auto it = row.attributes.find(columns[i].attribute.name);
    if (it == row.attributes.end()) {
      feature->SetFieldNull(field);
    } else {
      SetAttribute(*feature, field, it->second, columns[i].type);
    }
  }
  OGRPoint point(row.x, row.y);
  feature->SetGeometry(&point);
  if (layer.CreateFeature(feature.get()) != OGRERR_NONE) {
    throw CsvError(path + ": cannot write tree " + std::to_string(index + 1) + ": " +
                   LastGdalError());
  }
}

// The spatial reference of `crs` (EPSG:n, WKT or PROJ string), x = easting, y = northing. No
// CRS: GeoPackage's "Undefined Cartesian SRS" (srs_id -1), which says so; other formats none.
std::unique_ptr<OGRSpatialReference> SpatialReference(const std::string& crs, TreeFormat format,
                                                      const std::string& path) {
  if (crs.empty() && format != TreeFormat::kGeoPackage) return nullptr;
  auto srs = std::make_unique<OGRSpatialReference>();
  const std::string input = crs.empty() ? "LOCAL_CS[\"Undefined Cartesian SRS\"]" : crs;
  if (srs->SetFromUserInput(input.c_str()) != OGRERR_NONE) {
    throw CsvError(path + ": the map's CRS '" + crs.substr(0, 64) + "' is unknown to GDAL");
  }
  srs->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

std::vector<std::string> WriteLayer(GDALDataset& dataset, const std::vector<MapTreeRow>& rows,
                                    const LayerSpec& spec, const std::string& path,
                                    const GeoWriteProgress& progress,
                                    const std::vector<std::string>& order) {
  std::vector<Column> columns;
  std::vector<std::string> rounded;  // shapefile Real columns with values it cannot hold
  for (const ExportedAttribute& attribute : ExportedAttributes(rows, kGeoReserved, order)) {
    columns.push_back({attribute, AttributeType(rows, attribute.name)});
    if (spec.format != TreeFormat::kShapefile || columns.back().type != OFTReal) continue;
    for (const MapTreeRow& row : rows) {
      const auto it = row.attributes.find(attribute.name);
      if (it != row.attributes.end() && !ShapefileHolds(it->second)) {
        rounded.push_back(path + ": field '" + attribute.column + "': a shapefile keeps 15 " +
                          "decimals, so " + it->second + " (and any like it) is rounded");
        break;
      }
    }
  }
  OGRLayer* layer = &geo_internal::CreateLayer(dataset, spec, wkbPoint, path);
  std::vector<std::string> warnings = CreateFields(*layer, columns, path);
  warnings.insert(warnings.end(), rounded.begin(), rounded.end());
  // One transaction (GeoPackage): thousands of features commit at once.
  const bool transaction = dataset.StartTransaction() == OGRERR_NONE;
  for (size_t i = 0; i < rows.size(); ++i) {
    WriteFeature(*layer, rows[i], columns, i, path);
    if (progress) progress(static_cast<int64_t>(i + 1), std::ssize(rows));
  }
  if (transaction && dataset.CommitTransaction() != OGRERR_NONE) {
    throw CsvError(path + ": cannot commit: " + LastGdalError());
  }
  return warnings;
}

// The dataset to write into at `temporary`: for a GeoPackage, a copy of the one at `path` when
// there is one, without its layer `layer` (the other layers stay).
DatasetPtr OpenForWriting(GDALDriver& driver, TreeFormat format, const std::string& path,
                          const std::string& temporary, const std::string& layer) {
  std::error_code error;
  if (format == TreeFormat::kGeoPackage && fs::file_size(path, error) > 0 && !error) {
    fs::copy_file(path, temporary, error);
    if (error) throw CsvError(path + ": cannot copy to add a layer: " + error.message());
    const char* drivers[] = {"GPKG", nullptr};
    DatasetPtr dataset(static_cast<GDALDataset*>(
        GDALOpenEx(temporary.c_str(), GDAL_OF_VECTOR | GDAL_OF_UPDATE, drivers, nullptr, nullptr)));
    if (!dataset) {
      throw CsvError(path + ": exists and is not a GeoPackage (" + LastGdalError() +
                     "): remove it or choose another --out");
    }
    for (int i = 0; i < dataset->GetLayerCount(); ++i) {
      if (EQUAL(dataset->GetLayer(i)->GetName(), layer.c_str()) &&
          dataset->DeleteLayer(i) != OGRERR_NONE) {
        throw CsvError(path + ": cannot replace layer '" + layer + "': " + LastGdalError());
      }
    }
    return dataset;
  }
  DatasetPtr dataset(driver.Create(temporary.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  if (!dataset) throw CsvError(path + ": cannot create: " + LastGdalError());
  return dataset;
}

// GeoJSON cannot say "no CRS" through GDAL, which writes no crs member (WGS 84 to RFC 7946
// readers): GeoJSON 2008's `"crs": null` says it, after the collection's type.
void MarkNoCrs(const std::string& file, const std::string& path) {
  std::string text;
  {
    std::ifstream in(file, std::ios::binary);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::string type = "\"type\": \"FeatureCollection\",";
  const size_t at = text.find(type);
  const size_t brace = text.find('{');
  if (brace == std::string::npos) throw CsvError(path + ": GDAL wrote no GeoJSON object");
  text.insert(at == std::string::npos ? brace + 1 : at + type.size(), "\n\"crs\": null,");
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  if (!out) throw CsvError(path + ": cannot write");
}

// A shapefile is several files: written in a directory `temporary`, then moved beside `path`
// one by one; the parts of an earlier export this one does not write (an old .prj) are removed.
void PlaceShapefile(const std::string& temporary, const std::string& path) {
  const fs::path target(path);
  std::set<std::string> written;
  for (const fs::directory_entry& entry : fs::directory_iterator(temporary)) {
    written.insert(entry.path().extension().string());
  }
  std::vector<std::string> stale;
  for (const std::string& part : kShapefileParts) {
    if (!written.count(part)) stale.push_back(part);
  }
  RemoveSidecars(path, stale);
  for (const std::string& extension : written) {
    const fs::path to = fs::path(target).replace_extension(extension);
    MoveInto((fs::path(temporary) / target.filename()).replace_extension(extension).string(),
             to.string());
  }
  fs::remove_all(temporary);
}

}  // namespace

namespace geo_internal {

OGRLayer& CreateLayer(GDALDataset& dataset, const LayerSpec& spec, OGRwkbGeometryType type,
                      const std::string& path) {
  const char* shapefile_options[] = {"ENCODING=UTF-8", nullptr};  // and a .cpg saying so
  // GeoJSON in WGS 84 is written as RFC 7946 (longitude, latitude; no 2008 "crs" member), which
  // web tools expect.
  const char* rfc7946_options[] = {"RFC7946=YES", nullptr};
  const bool wgs84 = spec.srs != nullptr && spec.srs->GetAuthorityName(nullptr) != nullptr &&
                     std::string(spec.srs->GetAuthorityName(nullptr)) == "EPSG" &&
                     std::string(spec.srs->GetAuthorityCode(nullptr)) == "4326";
  char** options = nullptr;
  if (spec.format == TreeFormat::kShapefile) options = const_cast<char**>(shapefile_options);
  if (spec.format == TreeFormat::kGeoJson && wgs84) options = const_cast<char**>(rfc7946_options);
  OGRLayer* layer = dataset.CreateLayer(spec.name.c_str(), spec.srs, type, options);
  if (!layer) throw CsvError(path + ": cannot create a layer: " + LastGdalError());
  return *layer;
}

std::vector<std::string> WriteGeoFile(const std::string& path, TreeFormat format,
                                      const std::string& crs, const std::string& layer,
                                      const LayerWriter& write_layer) {
  RegisterGdal();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(DriverName(format));
  if (!driver || format == TreeFormat::kCsv) {
    throw CsvError(path + ": GDAL has no " + TreeFormatName(format) + " writer");
  }
  const std::unique_ptr<OGRSpatialReference> srs = SpatialReference(crs, format, path);
  const bool shapefile = format == TreeFormat::kShapefile;
  std::vector<std::string> warnings;
  const auto write = [&](const std::string& temporary) {
    std::string target = temporary;
    if (shapefile) {
      fs::create_directory(temporary);
      target = (fs::path(temporary) / fs::path(path).filename()).string();
    }
    CPLErrorReset();
    DatasetPtr dataset = OpenForWriting(*driver, format, path, target, layer);
    const std::string name = shapefile ? fs::path(path).stem().string() : layer;
    warnings = write_layer(*dataset, LayerSpec{name, format, srs.get()});
    dataset.reset();  // closes: GeoJSON and shapefiles are complete only now
    if (CPLGetLastErrorType() == CE_Failure) throw CsvError(path + ": " + LastGdalError());
    if (format == TreeFormat::kGeoJson && crs.empty()) MarkNoCrs(temporary, path);
    if (shapefile) PlaceShapefile(temporary, path);
  };
  if (shapefile) {
    const std::string directory = TemporaryBeside(path) + "d";
    try {
      write(directory);
    } catch (...) {
      std::error_code ignored;
      fs::remove_all(directory, ignored);
      throw;
    }
  } else {
    ReplaceFile(path, write);
  }
  return warnings;
}

}  // namespace geo_internal

std::vector<std::string> WriteGeoTrees(const std::string& path, TreeFormat format,
                                       const std::vector<MapTreeRow>& rows, const std::string& crs,
                                       const std::string& layer, const GeoWriteProgress& progress,
                                       const std::vector<std::string>& attribute_order) {
  return geo_internal::WriteGeoFile(
      path, format, crs, layer, [&](GDALDataset& dataset, const LayerSpec& spec) {
        return WriteLayer(dataset, rows, spec, path, progress, attribute_order);
      });
}

}  // namespace forestmap::client
