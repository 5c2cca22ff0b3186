#pragma once
// A map's survey boundary on the command line: `--boundary FILE` of `map create` and `map
// upload` (read and checked by io/boundary_io.h, put into the map's CRS as tree files are), and
// the boundary beside the trees of an export.

#include <CLI/CLI.hpp>
#include <optional>
#include <ostream>
#include <string>

#include "client/io/geo_io.h"
#include "client/lib/forestmap_client.h"

namespace forestmap::client {

// Adds --boundary FILE and --boundary-layer NAME to `command`, storing their text.
void AddBoundaryOptions(CLI::App& command, std::string& file, std::string& layer);

// The boundary of `path` (nullopt for an empty path) in the frame of map `map_name` whose CRS is
// `map_crs`: a file without a CRS (a CSV ring) is taken to be in the map's frame; one in another
// CRS than the map's is reprojected into it; one in degrees or feet is refused when the map has
// no CRS to take it to. Throws CommandError naming the file.
std::optional<Boundary> BoundaryForMap(const std::string& path, const std::string& layer,
                                       const std::string& map_name, const std::string& map_crs,
                                       std::ostream& log);

// The vertices of `boundary` from CRS `from` into CRS `to` (both known), as ReprojectTrees moves
// trees; `what` names the boundary in messages.
void ReprojectBoundary(Boundary& boundary, const std::string& what, const std::string& from,
                       const std::string& to, std::ostream& log);

// Where an export to `out` in `format` puts the map's boundary: a GeoPackage holds it as layer
// `boundary` of the same file (`survey_boundary` for a map named "boundary"); GeoJSON and
// shapefiles hold one layer a file, so it goes to a sibling file STEM.boundary.EXT; CSV has no
// place for polygons (nullopt).
struct BoundaryTarget {
  std::string path;
  std::string layer;
};
std::optional<BoundaryTarget> BoundaryTargetOf(const std::string& out, TreeFormat format,
                                               const std::string& map_name);

// Writes the boundary of an export beside its trees (BoundaryTargetOf), moved from the map's CRS
// into `to_crs` when that is given; `crs` is the CRS the file says. Returns where it went, for the
// user. Throws CommandError for a CSV (no place for polygons).
std::string ExportBoundary(Boundary boundary, const std::string& out, TreeFormat format,
                           const v1::Map& map, const std::string& to_crs, const std::string& crs);

}  // namespace forestmap::client
