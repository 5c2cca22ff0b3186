#pragma once
// Pictures of a map (cairo, the one file that includes it): stems to scale by DBH, candidate
// and confirmed trees told apart, optionally coloured by a category (species) and labelled, a grid
// with its coordinates in the map's CRS, a scale bar, a north arrow, the CRS, a DBH key and a
// legend of what is drawn; the map's survey boundary as a dashed outline; optionally one
// relocalization answer (sensor pose, range, matched and unmatched query trees) or a tracked path.
// SVG or PNG by the output's extension.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/core/polygon.h"

namespace forestmap::client {

// Every field has an initializer, so that {x, y, dbh, candidate} may leave the last ones out
// (-Wmissing-field-initializers).
struct PlotTree {
  double x = 0, y = 0;        // m, map frame (x east, y north)
  std::optional<double> dbh;  // m
  bool candidate = false;     // shared maps: not yet confirmed
  std::string label{};        // drawn beside the stem when PlotOptions::labels (e.g. its id)
  std::string category{};     // its class for colours (e.g. species) when the input has categories
};

struct PlotPose {
  double x = 0, y = 0;  // m, map frame
  double yaw = 0;       // rad, sensor x axis, counter-clockwise from map x
};

struct PlotInput {
  std::string title;  // e.g. the map's name and tree count
  std::string crs;    // e.g. "EPSG:2959 NAD83(CSRS) / UTM zone 18N"; empty: none
  std::vector<PlotTree> trees;
  std::string category_name;       // what PlotTree::category is (e.g. "species"); empty: no colours
  std::optional<PlotPose> sensor;  // one relocalization answer
  double sensor_range = 0;         // m, drawn as a circle around the sensor (0: none)
  std::vector<Eigen::Vector2d> matched;       // query trees on a map tree (map frame)
  std::vector<Eigen::Vector2d> unmatched;     // query trees on none
  std::vector<Eigen::Vector2d> path;          // a tracked path (map frame)
  std::vector<algorithms::Polygon> boundary;  // the map's survey boundary, drawn as an outline
};

struct PlotOptions {
  int size_px = 900;         // px, the longer side of the drawing
  double margin_m = 2.0;     // m, around what is drawn
  double min_stem_px = 1.5;  // px, stems smaller than this are drawn this big
  double unknown_dbh = 0.2;  // m, the drawn diameter of a stem of unknown DBH (outlined)
  bool labels = false;       // each tree's label beside its stem
  // Only this window of the map (m, map frame); empty: everything.
  std::optional<Eigen::Vector4d> window;  // min_x, min_y, max_x, max_y
};

// Categories with their own colour, the most frequent first (ties by name); the others are drawn
// grey as "other". A tree without a category ("") is "unknown".
inline constexpr size_t kMaxCategories = 8;
std::vector<std::string> ColouredCategories(const PlotInput& input);

// The legend's lines, in order: only what the picture shows.
std::vector<std::string> LegendOf(const PlotInput& input);

// The spacing of the coordinate grid (m): a round length (1, 2 or 5 times a power of ten) about a
// fifth of `width_m`; also the scale bar's length.
double GridStep(double width_m);

// Writes `path` (.svg or .png). Throws std::runtime_error naming the file when it cannot.
void WritePlot(const std::string& path, const PlotInput& input, const PlotOptions& options = {});

}  // namespace forestmap::client
