// Pictures of maps: stems land where they are, to scale, in both formats, over a grid of round
// coordinates; the legend lists only what is drawn; categories colour the stems.
#include "client/cli/map_plot.h"

#include <cairo.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;

// Colour of a pixel of an RGB24 image: 0xRRGGBB.
uint32_t Pixel(cairo_surface_t* image, int x, int y) {
  const unsigned char* data = cairo_image_surface_get_data(image);
  const int stride = cairo_image_surface_get_stride(image);
  return *reinterpret_cast<const uint32_t*>(data + y * stride + 4 * x) & 0xffffff;
}

TEST(MapPlotTest, PngShowsStemsToScaleAtTheirPlaces) {
  const fs::path path = fs::temp_directory_path() / ("plot_" + std::to_string(getpid()) + ".png");
  PlotInput input;
  input.title = "test";
  input.trees = {{0, 0, 1.0, false}, {20, 20, 1.0, true}, {10, 10, std::nullopt, false}};
  PlotOptions options;
  options.size_px = 240;  // 24 m (20 + 2 x 2 m margin) -> 10 px per m
  WritePlot(path.string(), input, options);
  cairo_surface_t* image = cairo_image_surface_create_from_png(path.c_str());
  ASSERT_EQ(cairo_surface_status(image), CAIRO_STATUS_SUCCESS);
  // Map area starts at (0, 44 px header); tree (0,0) is 2 m from the left and bottom edges.
  constexpr int kTop = 44;
  const int x0 = 20, y0 = kTop + 220;  // px of map (0, 0)
  const uint32_t confirmed = Pixel(image, x0, y0);
  EXPECT_GT((confirmed >> 8) & 0xff, (confirmed >> 16) & 0xff) << std::hex << confirmed;  // green
  // A 1 m stem is 10 px across: filled 3 px from its centre, background 7 px away.
  EXPECT_EQ(Pixel(image, x0 + 3, y0), confirmed);
  EXPECT_NE(Pixel(image, x0 + 7, y0), confirmed);
  // The candidate at (20, 20) is outlined: its ring is drawn, its centre is not.
  EXPECT_NE(Pixel(image, x0 + 200, y0 - 200), Pixel(image, x0 + 200 + 5, y0 - 200));
  cairo_surface_destroy(image);
  fs::remove(path);
}

TEST(MapPlotTest, GridLinesLieOnRoundCoordinatesOfTheMap) {
  const fs::path path = fs::temp_directory_path() / ("grid_" + std::to_string(getpid()) + ".png");
  PlotInput input;
  input.trees = {{0, 0, 0.3, false}, {100, 100, 0.3, false}};
  PlotOptions options;
  options.size_px = 520;  // 104 m (100 + 2 x 2 m margin) -> 5 px per m
  ASSERT_EQ(GridStep(104), 20);
  WritePlot(path.string(), input, options);
  cairo_surface_t* image = cairo_image_surface_create_from_png(path.c_str());
  ASSERT_EQ(cairo_surface_status(image), CAIRO_STATUS_SUCCESS);
  // World (x, 50) is at px ((x + 2) * 5, 44 + (102 - 50) * 5): empty ground, lines at 40 and 60.
  const auto at = [&](double x) { return Pixel(image, static_cast<int>((x + 2) * 5), 304); };
  const uint32_t ground = at(50);
  EXPECT_NE(at(40), ground);
  EXPECT_NE(at(60), ground);
  EXPECT_EQ(at(45), ground);
  EXPECT_EQ(at(41), ground);
  cairo_surface_destroy(image);
  fs::remove(path);
}

// The map's survey boundary is outlined where its rings run (holes too) and named in the legend.
TEST(MapPlotTest, TheSurveyBoundaryIsOutlined) {
  const fs::path path =
      fs::temp_directory_path() / ("boundary_" + std::to_string(getpid()) + ".png");
  PlotInput input;
  input.trees = {{5, 5, 0.3, false}, {15, 15, 0.3, false}};
  algorithms::Polygon square;
  square.outer = {{0, 0}, {20, 0}, {20, 20}, {0, 20}};
  square.holes = {{{8, 8}, {12, 8}, {12, 12}, {8, 12}}};
  input.boundary = {square};
  PlotOptions options;
  options.size_px = 240;  // 24 m (the boundary + 2 x 2 m margin) -> 10 px per m
  WritePlot(path.string(), input, options);
  cairo_surface_t* image = cairo_image_surface_create_from_png(path.c_str());
  ASSERT_EQ(cairo_surface_status(image), CAIRO_STATUS_SUCCESS);
  constexpr int kTop = 44;
  const auto px = [](double x) { return static_cast<int>(std::lround(20 + 10 * x)); };
  const auto py = [](double y) { return static_cast<int>(std::lround(kTop + 220 - 10 * y)); };
  // Violet ink: more blue than green, more red than green.
  const auto violet = [](uint32_t c) {
    const int r = (c >> 16) & 0xff, g = (c >> 8) & 0xff, b = c & 0xff;
    return b > 0x70 && b > g + 0x30 && r > g;
  };
  // Somewhere along each dashed ring (outer left edge, hole's left edge) the ink is violet.
  for (const double edge : {0.0, 8.0}) {
    int inked = 0;
    for (double y = 9; y <= 11; y += 0.1) inked += violet(Pixel(image, px(edge), py(y)));
    EXPECT_GT(inked, 0) << "edge x = " << edge;
  }
  for (double y = 9; y <= 11; y += 0.1) EXPECT_FALSE(violet(Pixel(image, px(4), py(y))));
  cairo_surface_destroy(image);
  fs::remove(path);
  EXPECT_EQ(LegendOf(input), (std::vector<std::string>{"confirmed stem", "survey boundary"}));
}

TEST(MapPlotTest, TheLegendListsOnlyWhatIsDrawn) {
  PlotInput survey;
  survey.trees = {{0, 0, 0.3, false}, {5, 5, 0.4, false}};
  EXPECT_EQ(LegendOf(survey), std::vector<std::string>{"confirmed stem"});
  PlotInput shared = survey;
  shared.trees.push_back({9, 1, std::nullopt, false});
  shared.trees.push_back({3, 8, 0.2, true});
  shared.matched = {{0, 0}};
  shared.sensor = PlotPose{1, 1, 0};
  EXPECT_EQ(LegendOf(shared),
            (std::vector<std::string>{"confirmed stem", "stem, DBH unknown", "candidate stem",
                                      "query: matched", "sensor (heading)"}));
}

TEST(MapPlotTest, CategoriesColourTheStemsMostFrequentFirstAndTheRestGrey) {
  PlotInput input;
  input.category_name = "species";
  input.trees = {{0, 0, 1.0, false, "1", "oak"},
                 {20, 0, 1.0, false, "2", "ash"},
                 {0, 20, 1.0, false, "3", "oak"},
                 {20, 20, 1.0, true, "4", ""}};
  EXPECT_EQ(LegendOf(input), (std::vector<std::string>{"species: oak", "species: ash",
                                                       "species: unknown", "outline: candidate"}));
  for (int i = 0; i < 9; ++i) {  // nine more kinds, one tree each: two of them do not get a colour
    input.trees.push_back({40.0 + i, 0, 0.5, false, "", "kind" + std::to_string(i)});
  }
  const std::vector<std::string> legend = LegendOf(input);
  ASSERT_EQ(legend.size(), kMaxCategories + 2) << legend.size();
  EXPECT_EQ(legend[kMaxCategories], "species: other");

  // The most frequent category's stem is drawn in the first colour (Okabe-Ito orange, E69E00).
  const fs::path path = fs::temp_directory_path() / ("kinds_" + std::to_string(getpid()) + ".png");
  input.trees.resize(4);
  PlotOptions options;
  options.size_px = 240;  // 24 m -> 10 px per m, tree (0, 0) at px (20, 44 + 220)
  options.labels = true;
  WritePlot(path.string(), input, options);
  cairo_surface_t* image = cairo_image_surface_create_from_png(path.c_str());
  ASSERT_EQ(cairo_surface_status(image), CAIRO_STATUS_SUCCESS);
  EXPECT_EQ(Pixel(image, 20, 264), 0xE69E00u) << std::hex << Pixel(image, 20, 264);
  // Its label "1" is ink to the right of the stem (5 px radius), where the ground was.
  bool ink = false;
  for (int x = 26; x < 34; ++x) {
    for (int y = 255; y < 264; ++y) ink = ink || Pixel(image, x, y) < 0x808080;
  }
  EXPECT_TRUE(ink);
  cairo_surface_destroy(image);
  fs::remove(path);
}

TEST(MapPlotTest, SvgIsWrittenAndBadNamesAreRefused) {
  const fs::path path = fs::temp_directory_path() / ("plot_" + std::to_string(getpid()) + ".svg");
  PlotInput input;
  input.trees = {{0, 0, 0.3, false}};
  input.crs = "EPSG:2959";
  WritePlot(path.string(), input);
  std::stringstream text;
  text << std::ifstream(path).rdbuf();
  EXPECT_NE(text.str().find("<svg"), std::string::npos);
  fs::remove(path);
  EXPECT_THROW(WritePlot((fs::temp_directory_path() / "plot.jpg").string(), input),
               std::runtime_error);
}

}  // namespace
}  // namespace forestmap::client
