// geo/crs.h on its own: which CRSs can hold a map (a plane in metres), points moved between CRSs
// as PROJ's command line (cs2cs) moves them, and the UTM zone of a point.

#include "geo/crs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

namespace forestmap::geo {
namespace {

constexpr double kMetreTolerance = 1e-6;  // m, against cs2cs's 12 decimals

// cs2cs -f %.12f FROM TO of "x y z", in the CRSs' own axis orders.
void Cs2cs(const std::string& crss, double& x, double& y, double z) {
  char command[256];
  std::snprintf(command, sizeof command, "echo '%.12f %.12f %.12f' | cs2cs -f %%.12f %s", x, y, z,
                crss.c_str());
  FILE* pipe = popen(command, "r");
  ASSERT_NE(pipe, nullptr);
  char line[256] = {};
  const bool read = std::fgets(line, sizeof line, pipe) != nullptr;
  pclose(pipe);
  ASSERT_TRUE(read) << "cs2cs gave no output (is proj-bin installed?)";
  std::istringstream(line) >> x >> y;
}

TEST(CrsTest, ProjectedCrsInMetresCanHoldAMap) {
  for (const char* crs : {"EPSG:2959", "EPSG:32618", "+proj=utm +zone=18 +ellps=GRS80",
                          "+proj=tmerc +lon_0=10 +towgs84=1,2,3", "EPSG:2959+5713"}) {
    const CrsInfo info = ParseCrs(crs);
    EXPECT_EQ(info.map_problem, "") << crs;
  }
}

TEST(CrsTest, DegreesFeetAndGeocentricCannotHoldAMap) {
  EXPECT_NE(ParseCrs("EPSG:4326").map_problem.find("geographic"), std::string::npos);
  EXPECT_NE(ParseCrs("EPSG:4979").map_problem.find("degrees"), std::string::npos);
  EXPECT_NE(ParseCrs("+proj=longlat +datum=WGS84").map_problem.find("geographic"),
            std::string::npos);
  EXPECT_NE(ParseCrs("EPSG:4978").map_problem.find("geocentric"), std::string::npos);
  const std::string feet = ParseCrs("EPSG:2263").map_problem;  // NY Long Island (ftUS)
  EXPECT_NE(feet.find("US survey foot (0.3048006096 m)"), std::string::npos) << feet;
  EXPECT_NE(ParseCrs("EPSG:5713").map_problem.find("no horizontal plane"), std::string::npos);
}

TEST(CrsTest, ReprojectionAgreesWithCs2cs) {
  const Reprojection to_utm("EPSG:4326", "EPSG:2959");
  double x = -75.25, y = 46.03, z = 123.0;  // longitude, latitude
  to_utm.Apply(x, y, z);
  double cx = 46.03, cy = -75.25;  // cs2cs takes EPSG:4326 as latitude, longitude
  Cs2cs("EPSG:4326 EPSG:2959", cx, cy, 123.0);
  EXPECT_NEAR(x, cx, kMetreTolerance);
  EXPECT_NEAR(y, cy, kMetreTolerance);
  EXPECT_EQ(z, 123.0);  // a 2-D target keeps heights

  const Reprojection from_feet("EPSG:2263", "EPSG:32618");
  double fx = 1000000.0, fy = 200000.0, fz = 0;
  from_feet.Apply(fx, fy, fz);
  double gx = 1000000.0, gy = 200000.0;
  Cs2cs("EPSG:2263 EPSG:32618", gx, gy, 0.0);
  EXPECT_NEAR(fx, gx, kMetreTolerance);
  EXPECT_NEAR(fy, gy, kMetreTolerance);

  double far_x = 1e30, far_y = 1e30, far_z = 0;
  EXPECT_THROW(to_utm.Apply(far_x, far_y, far_z), CrsError);
}

constexpr const char* kLocalGrid =
    R"(ENGCRS["Plot 25 local grid",EDATUM["Plot 25 origin"],CS[Cartesian,2],)"
    R"(AXIS["x",east,ORDER[1],LENGTHUNIT["metre",1]],AXIS["y",north,ORDER[2],LENGTHUNIT["metre",1]]])";

// A local grid in metres can hold a map, and has no way to WGS84: a CrsError with a reason (PROJ
// gives none itself), never a crash.
TEST(CrsTest, LocalGridHoldsAMapAndHasNoWayToWgs84) {
  EXPECT_EQ(ParseCrs(kLocalGrid).map_problem, "");
  try {
    MapToWgs84 to_wgs84(kLocalGrid);
    FAIL() << "a local grid transformed to WGS84";
  } catch (const CrsError& e) {
    EXPECT_NE(std::string(e.what()).find("no transformation"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Reprojection(kLocalGrid, "EPSG:2959"), CrsError);
}

// What PROJ says of the transformation to WGS84 travels with the pose: NAD83(CSRS) -> WGS 84 is
// stated to 1 or 2 m; a compound CRS whose geoid grid is not installed is a ballpark.
TEST(CrsTest, GeodeticPoseSaysHowGoodTheTransformationIs) {
  const GeodeticPose nad83 = MapToWgs84("EPSG:2959").Convert(312030, 5096040, 0, 0);
  EXPECT_GT(nad83.transformation.accuracy_m, 0);
  EXPECT_LE(nad83.transformation.accuracy_m, 2);
  EXPECT_FALSE(nad83.transformation.ballpark);
  const GeodeticPose wgs84 = MapToWgs84("EPSG:32618").Convert(312030, 5096040, 0, 0);
  EXPECT_FALSE(wgs84.transformation.ballpark);
  EXPECT_LE(wgs84.transformation.accuracy_m, 0);  // a conversion: exact (0), or none stated
  const GeodeticPose navd88 = MapToWgs84("EPSG:2959+5703").Convert(312030, 5096040, 100, 0);
  EXPECT_TRUE(navd88.transformation.ballpark);
}

TEST(CrsTest, GridScaleOnTheGround) {
  // Web Mercator at 46 N: a unit is cos(46 deg) metres on the ground (spherical formula vs the
  // ellipsoid: 0.2% apart).
  double x = -75.25, y = 46.0, z = 0;
  Reprojection("EPSG:4326", "EPSG:3857").Apply(x, y, z);
  EXPECT_NEAR(GridScaleAt("EPSG:3857", x, y), 1 / std::cos(46.0 * M_PI / 180), 0.005);
  // UTM: 0.9996 on the central meridian, about 1.0000 180 km from it.
  EXPECT_NEAR(GridScaleAt("EPSG:32618", 500000, 5096000), 0.9996, 1e-5);
  EXPECT_NEAR(GridScaleAt("EPSG:2959", 312030, 5096040), 1.0000, 2e-4);
  EXPECT_THROW(GridScaleAt(kLocalGrid, 0, 0), CrsError);
}

TEST(CrsTest, AreaOfUse) {
  const CrsInfo utm18 = ParseCrs("EPSG:2959");  // Canada, 78 W to 72 W
  ASSERT_TRUE(utm18.has_area);
  EXPECT_TRUE(utm18.InArea(-75.25, 46.03, 0));
  EXPECT_FALSE(utm18.InArea(-79.5, 46.0, 1.0));
  EXPECT_TRUE(utm18.InArea(-78.5, 46.0, 1.0));  // within the margin
  EXPECT_FALSE(utm18.InArea(117.0, 30.0, 1.0));
  EXPECT_FALSE(utm18.InArea(std::nan(""), 46.0, 1.0));
  const CrsInfo nztm = ParseCrs("EPSG:3851");  // NZ continental shelf: across the antimeridian
  ASSERT_TRUE(nztm.has_area);
  ASSERT_GT(nztm.west, nztm.east);
  EXPECT_TRUE(nztm.InArea(179.9, -40.0, 0));
  EXPECT_TRUE(nztm.InArea(-179.9, -40.0, 0));
  EXPECT_FALSE(nztm.InArea(0.0, -40.0, 1.0));
  EXPECT_TRUE(ParseCrs("EPSG:4326").InArea(123.0, -45.0, 0));  // the world
}

TEST(CrsTest, UtmZoneOfAPoint) {
  EXPECT_EQ(UtmZoneCrs(-75.25, 46.03), "EPSG:32618");
  EXPECT_EQ(UtmZoneCrs(10.5, -33.0), "EPSG:32732");
  EXPECT_EQ(UtmZoneCrs(-180.0, 0.0), "EPSG:32601");
  EXPECT_EQ(UtmZoneCrs(179.999, 0.0), "EPSG:32660");
  EXPECT_EQ(UtmZoneCrs(180.0, 0.0), "EPSG:32660");
  EXPECT_EQ(UtmZoneCrs(370.5, 10.0), "EPSG:32632");  // wrapped longitude
  EXPECT_THROW(UtmZoneCrs(0, 85.0), CrsError);
  EXPECT_THROW(UtmZoneCrs(0, std::nan("")), CrsError);
  EXPECT_THROW(UtmZoneCrs(std::nan(""), 0), CrsError);
}

}  // namespace
}  // namespace forestmap::geo
