// forestmapd's read-only web page in a real browser: Debian's headless Chromium loads
// the page from an in-process server, waits for the trees to draw (<body data-drawn="N">), and a
// screenshot must show the stems in their colour.

#include "server/http/http_page.h"

#include <cairo.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

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
constexpr uint32_t kStemColour = 0x216b33;  // the page's confirmed-stem fill
constexpr int kMinStemPixels = 62 * 4;      // 62 stems of at least a 1.5 px radius

std::string Chromium(const fs::path& profile) {
  return "chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
         "--disable-background-networking --disable-component-update --disable-sync "
         "--window-size=1100,800 --virtual-time-budget=10000 --user-data-dir='" +
         profile.string() + "' ";
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
  client.UploadTrees("prf025", client::ReadMapTreesCsv(kField, options), false, {});

  const fs::path dir = fs::temp_directory_path() / ("http_page_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string url = "'http://" + page.address() + "/#map=prf025'";
  const std::string dom = Output(Chromium(dir / "p1") + "--dump-dom " + url + " 2>/dev/null");
  EXPECT_NE(dom.find("data-drawn=\"62\""), std::string::npos) << dom.substr(0, 2000);
  EXPECT_NE(dom.find("prf025: 62 trees"), std::string::npos);

  const fs::path shot = dir / "page.png";
  Output(Chromium(dir / "p2") + "--screenshot='" + shot.string() + "' " + url + " 2>&1");
  cairo_surface_t* image = cairo_image_surface_create_from_png(shot.c_str());
  ASSERT_EQ(cairo_surface_status(image), CAIRO_STATUS_SUCCESS) << "no screenshot " << shot;
  const int width = cairo_image_surface_get_width(image);
  const int height = cairo_image_surface_get_height(image);
  const int stride = cairo_image_surface_get_stride(image);
  const unsigned char* data = cairo_image_surface_get_data(image);
  int stem_pixels = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const uint32_t pixel = *reinterpret_cast<const uint32_t*>(data + y * stride + 4 * x);
      stem_pixels += (pixel & 0xffffff) == kStemColour;
    }
  }
  cairo_surface_destroy(image);
  EXPECT_GE(stem_pixels, kMinStemPixels) << "screenshot " << shot;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace forestmap::server
