// forestmapd's read-only web page in a real browser: Debian's headless Chromium loads
// the page from an in-process server, waits for the trees to draw (<body data-drawn="N">), and a
// screenshot must show the stems in their colour; a 1,000,000-tree map shows its density, and
// its trees once the view holds few enough.

#include "server/http/http_page.h"

#include <cairo.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "client/io/tree_csv.h"
#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

namespace fs = std::filesystem;

const std::string kField =
    std::string(FORESTMAP_SHARED_DATA) + "/survey_vs_lidar/PRF025/PRF025_Field.csv";
constexpr uint32_t kStemColour = 0x216b33;      // the page's confirmed-stem fill
constexpr int kMinStemPixels = 62 * 4;          // 62 stems of at least a 1.5 px radius
constexpr uint32_t kBoundaryColour = 0x593f99;  // the page's survey boundary outline

std::string Chromium(const fs::path& profile) {
  return "chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
         "--disable-background-networking --disable-component-update --disable-sync "
         "--window-size=1100,800 --virtual-time-budget=10000 --user-data-dir='" +
         profile.string() + "' ";
}

// Pixels of `colour` (0xRRGGBB) in a PNG.
int PixelsOf(const std::string& png, uint32_t colour) {
  cairo_surface_t* image = cairo_image_surface_create_from_png(png.c_str());
  if (cairo_surface_status(image) != CAIRO_STATUS_SUCCESS) {
    cairo_surface_destroy(image);
    return -1;
  }
  const int width = cairo_image_surface_get_width(image);
  const int height = cairo_image_surface_get_height(image);
  const int stride = cairo_image_surface_get_stride(image);
  const unsigned char* data = cairo_image_surface_get_data(image);
  int count = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      count += (*reinterpret_cast<const uint32_t*>(data + y * stride + 4 * x) & 0xffffff) == colour;
    }
  }
  cairo_surface_destroy(image);
  return count;
}

std::string Output(const std::string& command) {
  FILE* pipe = popen(command.c_str(), "r");
  std::string out;
  char buffer[4096];
  while (pipe && std::fgets(buffer, sizeof(buffer), pipe)) out += buffer;
  if (pipe) pclose(pipe);
  return out;
}

TEST(HttpPageTest, ChromiumDrawsTheMapsTrees) {
  ASSERT_TRUE(fs::exists(kField)) << "no " << kField;
  storage::SqliteMapStore store(":memory:");
  ForestMapService service(store, {});
  ServerRunner runner("127.0.0.1:0", service);
  HttpPage page(store, service.recent_answers(), "127.0.0.1:0");
  client::ForestMapClient client(runner.address());
  client::TreeFileOptions options;
  options.columns = client::ParseColumnMapping("x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree");
  options.dbh_unit = client::DbhUnit::kCentimetre;
  client.CreateMap("prf025", "", "EPSG:2959");
  const std::vector<client::MapTreeRow> rows = client::ReadMapTreesCsv(kField, options);
  // The survey boundary: the trees' box and 2 m around it, outlined on the page.
  Eigen::AlignedBox2d box;
  for (const client::MapTreeRow& row : rows) box.extend(Eigen::Vector2d(row.x, row.y));
  algorithms::Polygon boundary;
  boundary.outer = {box.min() - Eigen::Vector2d(2, 2),
                    {box.max().x() + 2, box.min().y() - 2},
                    box.max() + Eigen::Vector2d(2, 2),
                    {box.min().x() - 2, box.max().y() + 2}};
  client.UploadTrees("prf025", rows, false, {}, client::Boundary{boundary});

  const fs::path dir = fs::temp_directory_path() / ("http_page_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string url = "'http://" + page.address() + "/#map=prf025'";
  const std::string dom = Output(Chromium(dir / "p1") + "--dump-dom " + url + " 2>/dev/null");
  EXPECT_NE(dom.find("data-drawn=\"62\""), std::string::npos) << dom.substr(0, 2000);
  EXPECT_NE(dom.find("prf025: 62 trees"), std::string::npos);
  EXPECT_NE(dom.find("data-boundary=\"1\""), std::string::npos) << dom.substr(0, 2000);

  const fs::path shot = dir / "page.png";
  Output(Chromium(dir / "p2") + "--screenshot='" + shot.string() + "' " + url + " 2>&1");
  EXPECT_GE(PixelsOf(shot.string(), kStemColour), kMinStemPixels) << "screenshot " << shot;
  EXPECT_GE(PixelsOf(shot.string(), kBoundaryColour), 100) << "screenshot " << shot;
  fs::remove_all(dir);
}

TEST(HttpPageTest, AMillionTreeMapShowsItsDensityThenTheTreesOfAViewThatHoldsFew) {
  constexpr int kSide = 1000, kTrees = kSide * kSide;  // a 5 km square, one tree per 25 m2
  constexpr double kSpacing = 5.0;
  storage::SqliteMapStore store(":memory:");
  std::vector<storage::TreeRecord> trees(kTrees);
  for (int i = 0; i < kTrees; ++i) {
    trees[i].x = (i % kSide) * kSpacing;
    trees[i].y = (i / kSide) * kSpacing;
    trees[i].dbh = 0.3;
  }
  store.CreateMap("huge", "", "");
  store.WriteTrees("huge", trees, storage::WriteMode::kReplace);
  ForestMapService service(store, {});
  HttpPage page(store, service.recent_answers(), "127.0.0.1:0");
  const fs::path dir = fs::temp_directory_path() / ("http_huge_" + std::to_string(getpid()));
  fs::create_directories(dir);

  // The whole map: its density, drawn in the stems' green (translucent: other shades).
  const std::string url = "'http://" + page.address() + "/#map=huge'";
  const auto start = std::chrono::steady_clock::now();
  const std::string dom = Output(Chromium(dir / "p1") + "--dump-dom " + url + " 2>/dev/null");
  RecordProperty(
      "density_page_seconds",
      std::to_string(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()));
  EXPECT_NE(dom.find("data-drawn=\"0\" data-view=\"density\""), std::string::npos)
      << dom.substr(0, 2000);
  EXPECT_NE(dom.find("huge: 1000000 trees"), std::string::npos);

  // A 200 m wide view: its trees, each drawn; a 1,100 x 800 window's canvas is about 800 px
  // high and wide, so the view holds about 40 x 40 trees (spacing 5 m) -- far fewer than 100,000.
  const std::string zoomed = "'http://" + page.address() + "/#map=huge&at=2500,2500,200'";
  const std::string near = Output(Chromium(dir / "p2") + "--dump-dom " + zoomed + " 2>/dev/null");
  const size_t at = near.find("data-drawn=\"");
  ASSERT_NE(at, std::string::npos) << near.substr(0, 2000);
  const int drawn = std::atoi(near.c_str() + at + 12);
  EXPECT_GT(drawn, 30 * 30) << near.substr(0, 2000);
  EXPECT_LT(drawn, 50 * 50) << near.substr(0, 2000);
  EXPECT_NE(near.find("data-view=\"trees\""), std::string::npos);
  const fs::path shot = dir / "near.png";
  Output(Chromium(dir / "p3") + "--screenshot='" + shot.string() + "' " + zoomed + " 2>&1");
  // Stems of 1.5 px radius (the smallest drawn): a few pixels of the exact fill colour each.
  EXPECT_GE(PixelsOf(shot.string(), kStemColour), 2 * drawn) << "screenshot " << shot;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace forestmap::server
