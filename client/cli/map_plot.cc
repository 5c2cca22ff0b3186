#include "client/cli/map_plot.h"

#include <cairo-svg.h>
#include <cairo.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace forestmap::client {
namespace {

constexpr double kLegendPx = 150;  // px of legend band on the right
constexpr double kHeaderPx = 44;   // px of title band on top

struct Rgb {
  double r, g, b;
};
constexpr Rgb kConfirmed{0.13, 0.42, 0.20};
constexpr Rgb kCandidate{0.93, 0.55, 0.10};
constexpr Rgb kMatched{0.10, 0.35, 0.85};
constexpr Rgb kUnmatched{0.85, 0.10, 0.10};
constexpr Rgb kInk{0.10, 0.10, 0.10};
constexpr Rgb kGrid{0.72, 0.74, 0.70};
constexpr Rgb kOther{0.55, 0.55, 0.55};
constexpr Rgb kBoundary{0.35, 0.25, 0.60};
// Okabe and Ito's colours, told apart with every common colour-vision deficiency.
constexpr std::array<Rgb, kMaxCategories> kCategoryColours = {{{0.90, 0.62, 0.00},
                                                               {0.34, 0.71, 0.91},
                                                               {0.00, 0.62, 0.45},
                                                               {0.94, 0.89, 0.26},
                                                               {0.00, 0.45, 0.70},
                                                               {0.84, 0.37, 0.00},
                                                               {0.80, 0.47, 0.65},
                                                               {0.00, 0.00, 0.00}}};

std::string CategoryText(const std::string& category) {
  return category.empty() ? "unknown" : category;
}

// The colour of each tree: its category's, or the confirmed green without categories.
class StemColours {
 public:
  explicit StemColours(const PlotInput& input)
      : coloured_(input.category_name.empty() ? std::vector<std::string>{}
                                              : ColouredCategories(input)),
        categories_(!input.category_name.empty()) {}
  Rgb Of(const PlotTree& tree) const {
    if (!categories_) return tree.candidate ? kCandidate : kConfirmed;
    const auto at = std::find(coloured_.begin(), coloured_.end(), CategoryText(tree.category));
    return at == coloured_.end() ? kOther : kCategoryColours[at - coloured_.begin()];
  }

 private:
  std::vector<std::string> coloured_;
  bool categories_;
};

// World (m) to picture (px): y up in the world, down in the picture.
struct View {
  double min_x, max_y, scale;  // px per m
  double left, top;            // px
  Eigen::Vector2d operator()(double x, double y) const {
    return {left + (x - min_x) * scale, top + (max_y - y) * scale};
  }
};

void SetColour(cairo_t* cr, Rgb c, double alpha = 1.0) {
  cairo_set_source_rgba(cr, c.r, c.g, c.b, alpha);
}

void Text(cairo_t* cr, double x, double y, const std::string& text, double size) {
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
  cairo_move_to(cr, x, y);
  cairo_show_text(cr, text.c_str());
}

void Stems(cairo_t* cr, const View& view, const PlotInput& input, const PlotOptions& o) {
  const StemColours colours(input);
  for (const PlotTree& tree : input.trees) {
    const Eigen::Vector2d p = view(tree.x, tree.y);
    const double diameter = tree.dbh.value_or(o.unknown_dbh);
    const double r = std::max(o.min_stem_px, 0.5 * diameter * view.scale);
    cairo_new_sub_path(cr);
    cairo_arc(cr, p.x(), p.y(), r, 0, 2 * M_PI);
    SetColour(cr, colours.Of(tree));
    if (tree.dbh && !tree.candidate) {
      cairo_fill(cr);
    } else {
      cairo_set_line_width(cr, 1.2);
      cairo_stroke(cr);
    }
    if (o.labels && !tree.label.empty()) {
      SetColour(cr, kInk, 0.8);
      Text(cr, p.x() + r + 1, p.y() - 1, tree.label, 8);
    }
  }
}

// Every ring of the boundary (outer rings and holes alike), dashed.
void BoundaryOutline(cairo_t* cr, const View& view, const PlotInput& input) {
  if (input.boundary.empty()) return;
  const auto ring_path = [&](const algorithms::Ring& ring) {
    for (size_t i = 0; i < ring.size(); ++i) {
      const Eigen::Vector2d p = view(ring[i].x(), ring[i].y());
      i == 0 ? cairo_move_to(cr, p.x(), p.y()) : cairo_line_to(cr, p.x(), p.y());
    }
    cairo_close_path(cr);
  };
  cairo_new_path(cr);
  for (const algorithms::Polygon& polygon : input.boundary) {
    ring_path(polygon.outer);
    for (const algorithms::Ring& hole : polygon.holes) ring_path(hole);
  }
  const double dashes[] = {8, 3};
  cairo_set_dash(cr, dashes, 2, 0);
  cairo_set_line_width(cr, 1.8);
  SetColour(cr, kBoundary);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
}

void Cross(cairo_t* cr, const Eigen::Vector2d& p, double r) {
  cairo_move_to(cr, p.x() - r, p.y() - r);
  cairo_line_to(cr, p.x() + r, p.y() + r);
  cairo_move_to(cr, p.x() - r, p.y() + r);
  cairo_line_to(cr, p.x() + r, p.y() - r);
  cairo_stroke(cr);
}

void Answer(cairo_t* cr, const View& view, const PlotInput& input) {
  cairo_set_line_width(cr, 1.5);
  if (input.path.size() > 1) {
    SetColour(cr, kMatched, 0.8);
    for (size_t i = 0; i < input.path.size(); ++i) {
      const Eigen::Vector2d p = view(input.path[i].x(), input.path[i].y());
      i == 0 ? cairo_move_to(cr, p.x(), p.y()) : cairo_line_to(cr, p.x(), p.y());
    }
    cairo_stroke(cr);
  }
  SetColour(cr, kMatched);
  for (const Eigen::Vector2d& q : input.matched) Cross(cr, view(q.x(), q.y()), 4);
  SetColour(cr, kUnmatched);
  for (const Eigen::Vector2d& q : input.unmatched) Cross(cr, view(q.x(), q.y()), 4);
  if (!input.sensor) return;
  const PlotPose& s = *input.sensor;
  const Eigen::Vector2d p = view(s.x, s.y);
  if (input.sensor_range > 0) {
    SetColour(cr, kMatched, 0.6);
    const double dashes[] = {6, 4};
    cairo_set_dash(cr, dashes, 2, 0);
    cairo_new_path(cr);
    cairo_arc(cr, p.x(), p.y(), input.sensor_range * view.scale, 0, 2 * M_PI);
    cairo_stroke(cr);
    cairo_set_dash(cr, nullptr, 0, 0);
  }
  // The sensor: a triangle pointing along its x axis.
  const double a = -s.yaw;  // picture y is down
  constexpr double kArrowPx = 20;
  SetColour(cr, kInk);
  cairo_move_to(cr, p.x() + kArrowPx * std::cos(a), p.y() + kArrowPx * std::sin(a));
  cairo_line_to(cr, p.x() + 0.6 * kArrowPx * std::cos(a + 2.4),
                p.y() + 0.6 * kArrowPx * std::sin(a + 2.4));
  cairo_line_to(cr, p.x() + 0.6 * kArrowPx * std::cos(a - 2.4),
                p.y() + 0.6 * kArrowPx * std::sin(a - 2.4));
  cairo_close_path(cr);
  cairo_fill(cr);
}

struct LegendEntry {
  Rgb colour;
  bool filled;
  std::string text;
};

std::vector<LegendEntry> LegendEntries(const PlotInput& input) {
  const auto any = [&](auto predicate) {
    return std::any_of(input.trees.begin(), input.trees.end(), predicate);
  };
  std::vector<LegendEntry> entries;
  if (!input.category_name.empty()) {  // a line per colour, then what an outline means
    const std::vector<std::string> coloured = ColouredCategories(input);
    for (size_t i = 0; i < coloured.size(); ++i) {
      entries.push_back({kCategoryColours[i], true, input.category_name + ": " + coloured[i]});
    }
    if (any([&](const PlotTree& t) {
          return std::find(coloured.begin(), coloured.end(), CategoryText(t.category)) ==
                 coloured.end();
        })) {
      entries.push_back({kOther, true, input.category_name + ": other"});
    }
    if (any([](const PlotTree& t) { return !t.candidate && !t.dbh; })) {
      entries.push_back({kInk, false, "outline: DBH unknown"});
    }
    if (any([](const PlotTree& t) { return t.candidate; })) {
      entries.push_back({kInk, false, "outline: candidate"});
    }
  } else {
    if (any([](const PlotTree& t) { return !t.candidate && t.dbh; })) {
      entries.push_back({kConfirmed, true, "confirmed stem"});
    }
    if (any([](const PlotTree& t) { return !t.candidate && !t.dbh; })) {
      entries.push_back({kConfirmed, false, "stem, DBH unknown"});
    }
    if (any([](const PlotTree& t) { return t.candidate; })) {
      entries.push_back({kCandidate, false, "candidate stem"});
    }
  }
  if (!input.matched.empty()) entries.push_back({kMatched, true, "query: matched"});
  if (!input.unmatched.empty()) entries.push_back({kUnmatched, true, "query: unmatched"});
  if (!input.boundary.empty()) entries.push_back({kBoundary, false, "survey boundary"});
  if (input.path.size() > 1) entries.push_back({kMatched, false, "tracked path"});
  if (input.sensor) entries.push_back({kInk, true, "sensor (heading)"});
  return entries;
}

// "123.5" for a grid label: as many decimals as the step needs.
std::string Coordinate(double value, double step) {
  const int decimals = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step)));
  char text[32];
  std::snprintf(text, sizeof(text), "%.*f", decimals, value);
  return text;
}

// Grid lines every GridStep in the map's coordinates, labelled along the bottom and the left
// edges of the map area, so that any tree can be located.
void Grid(cairo_t* cr, const View& view, const std::array<double, 4>& box) {
  const double step = GridStep(box[2] - box[0]);
  cairo_set_line_width(cr, 0.6);
  for (double x = std::ceil(box[0] / step) * step; x <= box[2]; x += step) {
    const Eigen::Vector2d bottom = view(x, box[1]), top = view(x, box[3]);
    SetColour(cr, kGrid);
    cairo_move_to(cr, bottom.x(), bottom.y());
    cairo_line_to(cr, top.x(), top.y());
    cairo_stroke(cr);
    SetColour(cr, kInk, 0.75);
    Text(cr, bottom.x() + 2, bottom.y() - 3, Coordinate(x, step), 9);
  }
  for (double y = std::ceil(box[1] / step) * step; y <= box[3]; y += step) {
    const Eigen::Vector2d left = view(box[0], y), right = view(box[2], y);
    SetColour(cr, kGrid);
    cairo_move_to(cr, left.x(), left.y());
    cairo_line_to(cr, right.x(), right.y());
    cairo_stroke(cr);
    SetColour(cr, kInk, 0.75);
    // Not at the bottom edge, where the x labels are.
    if (left.y() < view(box[0], box[1]).y() - 12) {
      Text(cr, left.x() + 2, left.y() - 3, Coordinate(y, step), 9);
    }
  }
}

// Circles of round DBHs drawn as the stems are (to scale, at least min_stem_px), under the
// legend: what a stem's size means at this scale.
void DbhKey(cairo_t* cr, const View& view, const PlotInput& input, const PlotOptions& o, double x,
            double y) {
  std::vector<double> dbh;
  for (const PlotTree& tree : input.trees) {
    if (tree.dbh) dbh.push_back(*tree.dbh);
  }
  if (dbh.empty()) return;
  std::sort(dbh.begin(), dbh.end());
  SetColour(cr, kInk);
  Text(cr, x - 6, y, "DBH key (to scale):", 10);
  y += 16;
  double last = -1;
  for (double quantile : {0.1, 0.5, 0.9}) {
    // Rounded to 5 cm (1 cm below 10 cm), each key different.
    const double value = dbh[static_cast<size_t>(quantile * (dbh.size() - 1))];
    const double unit = value < 0.1 ? 0.01 : 0.05;
    const double rounded = std::max(unit, std::round(value / unit) * unit);
    if (rounded <= last) continue;
    last = rounded;
    const double r = std::max(o.min_stem_px, 0.5 * rounded * view.scale);
    SetColour(cr, kConfirmed);
    cairo_new_path(cr);
    cairo_arc(cr, x + 6, y - 4, r, 0, 2 * M_PI);
    cairo_fill(cr);
    SetColour(cr, kInk);
    char label[32];
    std::snprintf(label, sizeof(label), "%.0f cm", rounded * 100);
    Text(cr, x + 12 + std::max(0.0, r - 6), y, label, 11);
    y += std::max(18.0, 2 * r + 6);
  }
}

void Furniture(cairo_t* cr, const View& view, double width_px, double height_px,
               const PlotInput& input, const PlotOptions& o) {
  SetColour(cr, kInk);
  Text(cr, 10, 20, input.title, 15);
  Text(cr, 10, 38, input.crs.empty() ? "no CRS (local map frame)" : "CRS: " + input.crs, 11);
  // Scale bar, bottom left.
  const double length = GridStep(width_px / view.scale);
  const double x0 = view.left + 10, y0 = height_px - 18;
  cairo_set_line_width(cr, 3);
  cairo_move_to(cr, x0, y0);
  cairo_line_to(cr, x0 + length * view.scale, y0);
  cairo_stroke(cr);
  char label[32];
  std::snprintf(label, sizeof(label), "%g m", length);
  Text(cr, x0 + length * view.scale + 6, y0 + 4, label, 12);
  // North arrow (grid north: the map's +y), top right of the map area.
  const double nx = width_px - kLegendPx - 24, ny = kHeaderPx + 16;
  cairo_move_to(cr, nx, ny);
  cairo_line_to(cr, nx - 7, ny + 22);
  cairo_line_to(cr, nx + 7, ny + 22);
  cairo_close_path(cr);
  cairo_fill(cr);
  Text(cr, nx - 5, ny + 38, "N", 13);
  // Legend.
  const double lx = width_px - kLegendPx + 12;
  double ly = kHeaderPx + 20;
  cairo_set_line_width(cr, 1.2);
  for (const LegendEntry& entry : LegendEntries(input)) {
    SetColour(cr, entry.colour);
    cairo_new_path(cr);
    cairo_arc(cr, lx, ly - 4, 5, 0, 2 * M_PI);
    entry.filled ? cairo_fill(cr) : cairo_stroke(cr);
    SetColour(cr, kInk);
    Text(cr, lx + 12, ly, entry.text, 11);
    ly += 18;
  }
  DbhKey(cr, view, input, o, lx, ly + 12);
}

std::array<double, 4> Extent(const PlotInput& input, const PlotOptions& o) {
  if (o.window) return {(*o.window)[0], (*o.window)[1], (*o.window)[2], (*o.window)[3]};
  std::array<double, 4> box = {INFINITY, INFINITY, -INFINITY, -INFINITY};
  const auto add = [&box](double x, double y) {
    box = {std::min(box[0], x), std::min(box[1], y), std::max(box[2], x), std::max(box[3], y)};
  };
  for (const PlotTree& t : input.trees) add(t.x, t.y);
  for (const Eigen::Vector2d& p : input.path) add(p.x(), p.y());
  for (const algorithms::Polygon& polygon : input.boundary) {
    for (const Eigen::Vector2d& p : polygon.outer) add(p.x(), p.y());
  }
  if (input.sensor) add(input.sensor->x, input.sensor->y);
  if (!std::isfinite(box[0])) box = {0, 0, 1, 1};
  return {box[0] - o.margin_m, box[1] - o.margin_m, box[2] + o.margin_m, box[3] + o.margin_m};
}

}  // namespace

std::vector<std::string> ColouredCategories(const PlotInput& input) {
  std::map<std::string, size_t> counts;
  for (const PlotTree& tree : input.trees) ++counts[CategoryText(tree.category)];
  std::vector<std::pair<std::string, size_t>> ranked(counts.begin(), counts.end());
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  std::vector<std::string> coloured;
  for (size_t i = 0; i < ranked.size() && i < kMaxCategories; ++i) {
    coloured.push_back(ranked[i].first);
  }
  return coloured;
}

std::vector<std::string> LegendOf(const PlotInput& input) {
  std::vector<std::string> lines;
  for (const LegendEntry& entry : LegendEntries(input)) lines.push_back(entry.text);
  return lines;
}

double GridStep(double width_m) {
  const double target = width_m / 5;
  const double power = std::pow(10.0, std::floor(std::log10(target)));
  for (double step : {5.0, 2.0, 1.0}) {
    if (step * power <= target) return step * power;
  }
  return power;
}

void WritePlot(const std::string& path, const PlotInput& input, const PlotOptions& o) {
  const std::array<double, 4> box = Extent(input, o);
  const double width_m = box[2] - box[0], height_m = box[3] - box[1];
  const double scale = o.size_px / std::max(width_m, height_m);
  const double width_px = std::ceil(width_m * scale) + kLegendPx;
  const double height_px = std::ceil(height_m * scale) + kHeaderPx + 30;
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".svg" && extension != ".png") {
    throw std::runtime_error(path + ": the picture's name must end in .svg or .png");
  }
  cairo_surface_t* surface =
      extension == ".svg"
          ? cairo_svg_surface_create(path.c_str(), width_px, height_px)
          : cairo_image_surface_create(CAIRO_FORMAT_RGB24, static_cast<int>(width_px),
                                       static_cast<int>(height_px));
  cairo_t* cr = cairo_create(surface);
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  const View view{box[0], box[3], scale, 0, kHeaderPx};
  cairo_rectangle(cr, 0, kHeaderPx, width_m * scale, height_m * scale);
  cairo_set_source_rgb(cr, 0.96, 0.97, 0.94);
  cairo_fill_preserve(cr);
  cairo_clip(cr);  // trees outside a --window stay outside
  Grid(cr, view, box);
  BoundaryOutline(cr, view, input);
  Stems(cr, view, input, o);
  Answer(cr, view, input);
  cairo_reset_clip(cr);
  Furniture(cr, view, width_px, height_px, input, o);
  cairo_destroy(cr);
  cairo_status_t status = cairo_surface_status(surface);
  if (status == CAIRO_STATUS_SUCCESS && extension == ".png") {
    status = cairo_surface_write_to_png(surface, path.c_str());
  }
  cairo_surface_finish(surface);
  if (status == CAIRO_STATUS_SUCCESS) status = cairo_surface_status(surface);
  cairo_surface_destroy(surface);
  if (status != CAIRO_STATUS_SUCCESS) {
    std::filesystem::remove(path);
    throw std::runtime_error(path +
                             ": cannot write the picture: " + cairo_status_to_string(status));
  }
}

}  // namespace forestmap::client
