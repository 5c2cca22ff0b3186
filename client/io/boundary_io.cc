// ReadBoundaryFile, CheckBoundaryPolygons and WriteGeoBoundary (boundary_io.h).
#include "client/io/boundary_io.h"

#include <cmath>
#include <filesystem>
#include <optional>

#include "client/io/csv_reader.h"
#include "client/io/geo_io_internal.h"
#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

using algorithms::Polygon;
using algorithms::Ring;
using geo_internal::DatasetPtr;
using geo_internal::FeaturePtr;
using geo_internal::LastGdalError;

std::string RingName(size_t polygon, size_t ring) {
  return StrCat({"polygon ", std::to_string(polygon + 1),
                 ring == 0 ? std::string(" outer ring") : " hole " + std::to_string(ring)});
}

// A GIS ring: closed (last vertex = first), returned without the repeated vertex.
Ring RingOf(const OGRLinearRing& ring, const std::string& where) {
  const int n = ring.getNumPoints();
  Ring points;
  points.reserve(n > 0 ? static_cast<size_t>(n) : 0);
  for (int i = 0; i < n; ++i) points.emplace_back(ring.getX(i), ring.getY(i));
  if (points.size() >= 2 && points.front() != points.back()) {
    throw CsvError(where + "is not closed (its last vertex is not its first)");
  }
  if (!points.empty()) points.pop_back();
  return points;
}

void AddPolygon(const OGRPolygon& polygon, const std::string& where,
                std::vector<Polygon>& polygons) {
  if (polygon.IsEmpty()) throw CsvError(where + "an empty polygon");
  Polygon added;
  const size_t index = polygons.size();
  added.outer = RingOf(*polygon.getExteriorRing(), StrCat({where, RingName(index, 0), ": "}));
  for (int h = 0; h < polygon.getNumInteriorRings(); ++h) {
    added.holes.push_back(
        RingOf(*polygon.getInteriorRing(h),
               StrCat({where, RingName(index, static_cast<size_t>(h) + 1), ": "})));
  }
  polygons.push_back(std::move(added));
}

bool HasPolygons(OGRLayer& layer) {
  const OGRwkbGeometryType type = wkbFlatten(layer.GetGeomType());
  return type == wkbPolygon || type == wkbMultiPolygon || type == wkbUnknown;
}

OGRLayer& ChooseBoundaryLayer(GDALDataset& dataset, const std::string& name,
                              const std::string& path) {
  if (!name.empty()) {
    OGRLayer* layer = dataset.GetLayerByName(name.c_str());
    if (!layer) throw CsvError(path + ": no layer named '" + name + "'");
    return *layer;
  }
  if (dataset.GetLayerCount() == 1) return *dataset.GetLayer(0);
  OGRLayer* found = nullptr;
  for (int i = 0; i < dataset.GetLayerCount(); ++i) {
    if (!HasPolygons(*dataset.GetLayer(i))) continue;
    if (found) throw CsvError(path + ": several layers have polygons: name the boundary's layer");
    found = dataset.GetLayer(i);
  }
  if (!found) throw CsvError(path + ": no layer has polygons (a survey boundary is a polygon)");
  return *found;
}

// Whether every vertex could be a longitude and latitude (RFC 7946's WGS 84).
bool InLongitudeLatitude(const std::vector<Polygon>& polygons) {
  for (const Polygon& polygon : polygons) {
    for (const Eigen::Vector2d& p : polygon.outer) {
      if (std::fabs(p.x()) > 180 || std::fabs(p.y()) > 90) return false;
    }
  }
  return true;
}

BoundaryFile ReadGisBoundary(const std::string& path, const std::string& layer_name) {
  geo_internal::RegisterGdal();
  CPLErrorReset();
  DatasetPtr dataset(static_cast<GDALDataset*>(
      GDALOpenEx(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, nullptr, nullptr)));
  if (!dataset) throw CsvError(path + ": not a readable GIS file: " + LastGdalError());
  if (dataset->GetLayerCount() < 1) throw CsvError(path + ": no layer");
  OGRLayer& layer = ChooseBoundaryLayer(*dataset, layer_name, path);
  BoundaryFile file;
  layer.ResetReading();
  int64_t number = 0;
  while (FeaturePtr feature{layer.GetNextFeature()}) {
    ++number;
    const std::string where = StrCat({path, ": feature ", std::to_string(number), ": "});
    const OGRGeometry* geometry = feature->GetGeometryRef();
    if (!geometry || geometry->IsEmpty()) throw CsvError(where + "no geometry");
    const OGRwkbGeometryType type = wkbFlatten(geometry->getGeometryType());
    if (type == wkbPolygon) {
      AddPolygon(*geometry->toPolygon(), where, file.polygons);
    } else if (type == wkbMultiPolygon) {
      for (const OGRPolygon* part : *geometry->toMultiPolygon()) {
        AddPolygon(*part, where, file.polygons);
      }
    } else {
      throw CsvError(StrCat({where, "a ", OGRGeometryTypeToName(type),
                             ", not a polygon (a survey boundary is a Polygon or MultiPolygon)"}));
    }
  }
  if (file.polygons.empty()) throw CsvError(path + ": no polygon");
  file.crs_wkt =
      geo_internal::DeclaredLayerCrs(*dataset, layer, path, InLongitudeLatitude(file.polygons));
  return file;
}

// One ring: columns x and y (any case), one row per vertex.
BoundaryFile ReadCsvRing(const std::string& path) {
  CsvReader reader = CsvReader::Open(path);
  std::optional<size_t> x, y;
  for (size_t i = 0; i < reader.header().size(); ++i) {
    std::string name = reader.header()[i];
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (name == "x") x = i;
    if (name == "y") y = i;
  }
  if (!x || !y) throw CsvError(path + ": a boundary ring needs columns x and y");
  Ring ring;
  while (reader.Next()) {
    Eigen::Vector2d vertex;
    for (int axis = 0; axis < 2; ++axis) {
      const size_t column = axis == 0 ? *x : *y;
      const std::string text(reader.fields()[column].text);
      char* end = nullptr;
      vertex[axis] = std::strtod(text.c_str(), &end);
      if (text.empty() || end != text.c_str() + text.size()) {
        throw CsvError(StrCat({path, ":", std::to_string(reader.line()), ": column '",
                               reader.header()[column], "': '", text, "' is not a number"}));
      }
    }
    if (ring.size() >= kMaxBoundaryVertices + 1) {
      throw CsvError(
          StrCat({path, ": more than ", std::to_string(kMaxBoundaryVertices), " vertices"}));
    }
    ring.push_back(vertex);
  }
  if (ring.size() >= 2 && ring.front() == ring.back()) ring.pop_back();  // closed or not
  BoundaryFile file;
  file.polygons.push_back({std::move(ring), {}});
  return file;
}

// Drops a vertex repeated right after itself (and a last one equal to the first).
void DropRepeats(Ring& ring) {
  Ring kept;
  kept.reserve(ring.size());
  for (const Eigen::Vector2d& p : ring) {
    if (kept.empty() || p != kept.back()) kept.push_back(p);
  }
  while (kept.size() > 1 && kept.back() == kept.front()) kept.pop_back();
  ring = std::move(kept);
}

OGRLinearRing GdalRing(const Ring& ring) {
  OGRLinearRing out;
  for (const Eigen::Vector2d& p : ring) out.addPoint(p.x(), p.y());
  out.closeRings();
  return out;
}

OGRPolygon GdalPolygon(const Polygon& polygon) {
  OGRPolygon out;
  OGRLinearRing outer = GdalRing(polygon.outer);
  out.addRing(&outer);
  for (const Ring& hole : polygon.holes) {
    OGRLinearRing ring = GdalRing(hole);
    out.addRing(&ring);
  }
  return out;
}

}  // namespace

void CheckBoundaryPolygons(const std::vector<Polygon>& polygons, const std::string& path) {
  if (polygons.empty()) throw CsvError(path + ": no polygon");
  size_t vertices = 0;
  for (size_t p = 0; p < polygons.size(); ++p) {
    for (size_t r = 0; r <= polygons[p].holes.size(); ++r) {
      const Ring& ring = r == 0 ? polygons[p].outer : polygons[p].holes[r - 1];
      const std::string where = StrCat({path, ": ", RingName(p, r), ": "});
      for (const Eigen::Vector2d& v : ring) {
        if (!v.allFinite()) throw CsvError(where + "a vertex is not finite");
      }
      if (ring.size() < 3) {
        throw CsvError(StrCat(
            {where, std::to_string(ring.size()), " distinct vertices; a ring needs at least 3"}));
      }
      if (!(std::fabs(algorithms::SignedArea(ring)) > 0)) {
        throw CsvError(where + "encloses no area (its vertices lie on a line)");
      }
      vertices += ring.size();
    }
    if (vertices > kMaxBoundaryVertices) {
      throw CsvError(StrCat({path, ": more than ", std::to_string(kMaxBoundaryVertices),
                             " vertices (simplify the boundary, e.g. ogr2ogr -simplify 0.5)"}));
    }
    CPLErrorReset();
    if (OGRGeometryFactory::haveGEOS() && !GdalPolygon(polygons[p]).IsValid()) {
      throw CsvError(StrCat({path, ": polygon ", std::to_string(p + 1),
                             " is not valid (a ring crosses itself or another ring, or a hole "
                             "lies outside its outer ring)"}));
    }
  }
}

BoundaryFile ReadBoundaryFile(const std::string& path, const std::string& layer) {
  if (!std::filesystem::exists(path)) throw CsvError(path + ": cannot open: no such file");
  BoundaryFile file =
      TreeFormatOfPath(path) == TreeFormat::kCsv ? ReadCsvRing(path) : ReadGisBoundary(path, layer);
  for (Polygon& polygon : file.polygons) {
    DropRepeats(polygon.outer);
    for (Ring& hole : polygon.holes) DropRepeats(hole);
  }
  CheckBoundaryPolygons(file.polygons, path);
  return file;
}

void WriteGeoBoundary(const std::string& path, TreeFormat format,
                      const std::vector<Polygon>& polygons, const std::string& crs,
                      const std::string& layer) {
  geo_internal::WriteGeoFile(
      path, format, crs, layer, [&](GDALDataset& dataset, const geo_internal::LayerSpec& spec) {
        OGRLayer& out = geo_internal::CreateLayer(dataset, spec, wkbPolygon, path);
        OGRFieldDefn field("polygon", OFTInteger);
        if (out.CreateField(&field) != OGRERR_NONE) {
          throw CsvError(path + ": cannot create field 'polygon': " + LastGdalError());
        }
        for (size_t i = 0; i < polygons.size(); ++i) {
          FeaturePtr feature(OGRFeature::CreateFeature(out.GetLayerDefn()));
          feature->SetField(0, static_cast<int>(i));
          OGRPolygon geometry = GdalPolygon(polygons[i]);
          feature->SetGeometry(&geometry);
          if (out.CreateFeature(feature.get()) != OGRERR_NONE) {
            throw CsvError(path + ": cannot write the boundary: " + LastGdalError());
          }
        }
        return std::vector<std::string>{};
      });
}

}  // namespace forestmap::client
