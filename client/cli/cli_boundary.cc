#include "client/cli/cli_boundary.h"

#include <filesystem>
#include <vector>

#include "client/cli/cli_context.h"
#include "client/cli/cli_format.h"
#include "client/cli/cli_tree_crs.h"
#include "client/io/boundary_io.h"
#include "geo/crs.h"

namespace forestmap::client {

void AddBoundaryOptions(CLI::App& command, std::string& file, std::string& layer) {
  command.add_option("--boundary", file,
                     "The survey's boundary, what the map covers: polygons (with holes) of a "
                     ".gpkg / .geojson / .shp file, or a CSV ring (columns x,y, one row per "
                     "vertex); without it the server derives the covered area from the trees");
  command.add_option("--boundary-layer", layer,
                     "The layer of --boundary to read (default: the only one with polygons)");
}

void ReprojectBoundary(Boundary& boundary, const std::string& what, const std::string& from,
                       const std::string& to, std::ostream& log) {
  std::vector<MapTreeRow> rows;
  const auto each_ring = [&](const auto& body) {
    for (algorithms::Polygon& polygon : boundary) {
      body(polygon.outer);
      for (algorithms::Ring& hole : polygon.holes) body(hole);
    }
  };
  each_ring([&](algorithms::Ring& ring) {
    for (const Eigen::Vector2d& p : ring) {
      MapTreeRow row;
      row.x = p.x();
      row.y = p.y();
      rows.push_back(row);
    }
  });
  ReprojectTrees(rows, what, from, to, log);
  size_t next = 0;
  each_ring([&](algorithms::Ring& ring) {
    for (Eigen::Vector2d& p : ring) {
      p = {rows[next].x, rows[next].y};
      ++next;
    }
  });
}

std::optional<Boundary> BoundaryForMap(const std::string& path, const std::string& layer,
                                       const std::string& map_name, const std::string& map_crs,
                                       std::ostream& log) {
  if (path.empty()) return std::nullopt;
  BoundaryFile file;
  try {
    file = ReadBoundaryFile(path, layer);
  } catch (const CsvError& e) {
    throw CommandError(std::string("--boundary ") + e.what());
  }
  const std::string& from = file.crs_wkt;
  if (from.empty()) return std::move(file.polygons);  // in the map's frame, as a CSV's trees
  try {
    if (map_crs.empty()) {
      const geo::CrsInfo info = geo::ParseCrs(from);
      if (!info.map_problem.empty()) {
        throw CommandError(path + ": the boundary's CRS " + DescribedCrs(from) +
                           " cannot be a map's: " + info.map_problem + ", and map '" + map_name +
                           "' has no CRS to reproject it into");
      }
      log << "forestmap: warning: map '" << map_name << "' has no CRS; the boundary of " << path
          << " (" << DescribedCrs(from) << ") is taken as it is" << std::endl;
    } else if (!SameCrs(from, map_crs)) {
      ReprojectBoundary(file.polygons, path, from, map_crs, log);
      CheckBoundaryPolygons(file.polygons, path);  // still valid after the move
    }
  } catch (const geo::CrsError& e) {
    throw CommandError(path + ": " + e.what());
  } catch (const CsvError& e) {
    throw CommandError(std::string("--boundary ") + e.what());
  }
  return std::move(file.polygons);
}

std::optional<BoundaryTarget> BoundaryTargetOf(const std::string& out, TreeFormat format,
                                               const std::string& map_name) {
  switch (format) {
    case TreeFormat::kGeoPackage:
      return BoundaryTarget{out, map_name == "boundary" ? "survey_boundary" : "boundary"};
    case TreeFormat::kGeoJson:
    case TreeFormat::kShapefile: {
      std::filesystem::path sibling(out);
      const std::string extension = sibling.extension().string();
      sibling.replace_extension(".boundary" + extension);
      return BoundaryTarget{sibling.string(), "boundary"};
    }
    default:
      return std::nullopt;
  }
}

std::string ExportBoundary(Boundary boundary, const std::string& out, TreeFormat format,
                           const v1::Map& map, const std::string& to_crs, const std::string& crs) {
  const std::optional<BoundaryTarget> target = BoundaryTargetOf(out, format, map.name());
  if (!target)
    throw CommandError("a " + std::string(TreeFormatName(format)) + " file holds no polygons");
  if (!to_crs.empty()) {
    try {
      const geo::Reprojection move(map.crs(), to_crs);
      const auto move_ring = [&move](algorithms::Ring& ring) {
        for (Eigen::Vector2d& p : ring) {
          double z = 0;
          move.Apply(p.x(), p.y(), z);
        }
      };
      for (algorithms::Polygon& polygon : boundary) {
        move_ring(polygon.outer);
        for (algorithms::Ring& hole : polygon.holes) move_ring(hole);
      }
    } catch (const geo::CrsError& e) {
      throw CommandError(std::string("--to-crs ") + to_crs + ": the boundary: " + e.what());
    }
  }
  try {
    WriteGeoBoundary(target->path, format, boundary, crs, target->layer);
  } catch (const CsvError& e) {
    throw CommandError(e.what());
  }
  return "the survey boundary (" + std::to_string(boundary.size()) + " polygons) to " +
         target->path +
         (format == TreeFormat::kGeoPackage ? " (layer '" + target->layer + "')" : "");
}

}  // namespace forestmap::client
