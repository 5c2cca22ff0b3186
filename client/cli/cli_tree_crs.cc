// The CRS of tree files on their way into a map: reprojection, checks, descriptions
// (cli_tree_crs.h).

#include "client/cli/cli_tree_crs.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "algorithms/core/kdtree.h"
#include "client/cli/cli_context.h"
#include "geo/crs.h"

namespace forestmap::client {

void AddToCrsOption(CLI::App& command, std::string& to_crs) {
  command.add_option("--to-crs", to_crs,
                     "Reproject the trees' x, y from the file's CRS (or --crs) into this one (an "
                     "EPSG code, WKT or PROJ string in metres; utm: the WGS 84 / UTM zone of the "
                     "trees), which the map takes; needed for files in degrees or feet");
}

namespace {

geo::CrsInfo ParseCrsOf(const std::string& what, const std::string& crs) {
  try {
    return geo::ParseCrs(crs);
  } catch (const geo::CrsError& e) {
    throw CommandError(what + ": CRS '" + ShortCrs(crs) + "' is not one PROJ knows (" + e.what() +
                       "); give an EPSG code (EPSG:2959), WKT or a PROJ string");
  }
}

std::string Described(const geo::CrsInfo& info) {
  return info.epsg > 0 ? "EPSG:" + std::to_string(info.epsg) + " (" + info.name + ")" : info.name;
}

// The centre of `rows`, in their CRS.
std::array<double, 2> Centre(const std::vector<MapTreeRow>& rows) {
  double x = 0, y = 0;
  for (const MapTreeRow& row : rows) {
    x += row.x / static_cast<double>(rows.size());
    y += row.y / static_cast<double>(rows.size());
  }
  return {x, y};
}

// The centre of `rows` (in `crs`) in WGS 84 degrees: {longitude, latitude}. Throws CrsError.
std::array<double, 2> CentreLonLat(const std::vector<MapTreeRow>& rows, const std::string& crs) {
  auto [x, y] = Centre(rows);
  double z = 0;
  geo::Reprojection(crs, "EPSG:4326").Apply(x, y, z);
  return {x, y};
}

// The WGS 84 / UTM zone of the centre of `rows`, which are in `from`.
std::string UtmZoneOf(const std::vector<MapTreeRow>& rows, const std::string& from) {
  const auto [longitude, latitude] = CentreLonLat(rows, from);
  return geo::UtmZoneCrs(longitude, latitude);
}

void WarnIfNotMetres(const std::vector<MapTreeRow>& rows, const std::string& path,
                     std::ostream& log) {
  constexpr size_t kMinTrees = 10;           // fewer say little about spacing
  constexpr size_t kSampled = 2000;          // trees whose nearest neighbour is measured
  constexpr double kCloserThanTrees = 0.05;  // m: stems' centres are at least a DBH apart
  if (rows.size() < kMinTrees) return;
  std::vector<std::array<double, 2>> points;
  points.reserve(rows.size());
  for (const MapTreeRow& row : rows) points.push_back({row.x, row.y});
  const algorithms::KdTree<double, 2> index(std::move(points));
  std::vector<double> nearest;
  const size_t step = std::max<size_t>(1, rows.size() / kSampled);
  for (size_t i = 0; i < rows.size(); i += step) {
    const auto two = index.Knn(index.point(i), 2);  // itself, then its nearest neighbour
    if (two.size() == 2) nearest.push_back(std::sqrt(two[1].second));
  }
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  const double median = nearest[nearest.size() / 2];
  if (median >= kCloserThanTrees) return;
  log << "forestmap: warning: " << path << ": half the trees are closer than " << median
      << " to their nearest neighbour, and trees stand further apart than 0.05 m: are x and y "
         "metres? (for degrees: --crs EPSG:4326 --to-crs utm)"
      << std::endl;
}

// Warns when the trees' centre lies outside the area of use of `crs`, or where a unit of `crs`
// is not a metre on the ground (Web Mercator: 1/cos(latitude)), or off the Earth.
void WarnIfMisplaced(const std::vector<MapTreeRow>& rows, const std::string& path,
                     const std::string& crs, std::ostream& log) {
  constexpr double kMarginDeg = 1.0;       // CRSs are used a little beyond their official area
  constexpr double kMaxScaleError = 0.01;  // 1%: 0.5 m over a 50 m view
  const geo::CrsInfo info = ParseCrsOf(path, crs);
  std::array<double, 2> lon_lat{};
  double scale = 1;
  try {
    lon_lat = CentreLonLat(rows, crs);
    const auto [x, y] = Centre(rows);
    scale = geo::GridScaleAt(crs, x, y);
  } catch (const geo::CrsError& e) {
    if (!info.projected) return;  // a local grid has no way to the Earth
    log << "forestmap: warning: " << path << ": the trees' centre does not map onto the Earth in "
        << Described(info) << " (" << e.what() << "): is that the trees' CRS?" << std::endl;
    return;
  }
  if (!info.InArea(lon_lat[0], lon_lat[1], kMarginDeg)) {
    log << "forestmap: warning: " << path << ": the trees' centre (longitude " << lon_lat[0]
        << ", latitude " << lon_lat[1] << ") is outside the area of use of " << Described(info)
        << " (" << info.area << "): is that the trees' CRS?" << std::endl;
  }
  if (std::abs(scale - 1) > kMaxScaleError) {
    log << "forestmap: warning: " << path << ": a metre of " << Described(info) << " is "
        << 1 / scale << " m on the ground where the trees are: a drone's metres will not match "
        << "the map's; reproject with --to-crs utm" << std::endl;
  }
}

}  // namespace

std::string ReprojectTrees(std::vector<MapTreeRow>& rows, const std::string& path,
                           const std::string& from, const std::string& to, std::ostream& log) {
  try {
    if (to.empty()) {
      if (from.empty()) return from;
      const geo::CrsInfo info = ParseCrsOf(path, from);
      if (info.map_problem.empty()) return from;
      std::string hint = "--to-crs utm";
      if (!rows.empty()) hint += " (here " + UtmZoneOf(rows, from) + ")";
      throw CommandError(path + ": its CRS " + Described(info) + " cannot be " +
                         "a map's: " + info.map_problem + ", and a map's x and y are metres; " +
                         "add " + hint + " or --to-crs EPSG:n to reproject the trees");
    }
    if (from.empty()) {
      throw CommandError(path +
                         ": --to-crs needs the CRS the trees are in, and the file "
                         "declares none: give it with --crs");
    }
    const geo::CrsInfo from_info = ParseCrsOf(path, from);
    const std::string target = to == "utm" ? (rows.empty() ? "" : UtmZoneOf(rows, from)) : to;
    if (target.empty()) return from;  // no trees: nothing tells the zone
    const geo::CrsInfo target_info = ParseCrsOf("--to-crs", target);
    if (!target_info.map_problem.empty()) {
      throw CommandError("--to-crs " + Described(target_info) +
                         " cannot be a map's: " + target_info.map_problem);
    }
    const geo::Reprojection move(from, target);
    for (size_t i = 0; i < rows.size(); ++i) {
      double z = rows[i].z.value_or(0);  // moved too, then dropped: heights are kept
      try {
        move.Apply(rows[i].x, rows[i].y, z);
      } catch (const geo::CrsError& e) {
        throw CommandError(path + ": tree " + std::to_string(i + 1) + " (" +
                           std::to_string(rows[i].x) + ", " + std::to_string(rows[i].y) +
                           "): " + e.what());
      }
    }
    log << path << ": " << rows.size() << " trees reprojected from " << Described(from_info)
        << " to " << Described(target_info) << std::endl;
    return target_info.Canonical();
  } catch (const geo::CrsError& e) {
    throw CommandError(path + ": " + e.what());
  }
}

void CheckTreePlacement(const std::vector<MapTreeRow>& rows, const std::string& path,
                        const std::string& crs, std::ostream& log) {
  WarnIfNotMetres(rows, path, log);
  if (!crs.empty() && !rows.empty()) WarnIfMisplaced(rows, path, crs, log);
}

std::string CrsOfTrees(const std::string& path, const std::string& given,
                       const std::string& declared) {
  if (given.empty()) return declared;
  if (!declared.empty() && !SameCrs(given, declared)) {
    throw CommandError(path + " declares its CRS, " + DescribedCrs(declared) + "; --crs " +
                       DescribedCrs(given) +
                       " would relabel its coordinates without moving them: to move them into " +
                       "that CRS use --to-crs (map create) or upload into a map in it");
  }
  return given;
}

bool InMetres(const std::string& crs) {
  return crs.empty() || ParseCrsOf("the CRS", crs).map_problem.empty();
}

bool SameCrs(const std::string& a, const std::string& b) {
  return ParseCrsOf("the CRS", a).Canonical() == ParseCrsOf("the CRS", b).Canonical();
}

std::string DescribedCrs(const std::string& crs) {
  try {
    return Described(geo::ParseCrs(crs));
  } catch (const geo::CrsError&) {
    return ShortCrs(crs);
  }
}

}  // namespace forestmap::client
