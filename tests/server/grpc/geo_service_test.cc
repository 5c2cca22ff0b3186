// Maps with a real CRS: CreateMap validates the CRS with PROJ and describes it (WKT,
// EPSG); Relocalize answers on such a map carry the sensor's WGS84 pose, checked against PROJ's
// own command line (cs2cs) and the transverse Mercator grid convergence.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "client/io/tree_csv.h"
#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

const std::string kField =
    std::string(FORESTMAP_SHARED_DATA) + "/survey_vs_lidar/PRF025/PRF025_Field.csv";
constexpr double kDegreeTolerance = 1e-7;        // deg, the bar against cs2cs
constexpr double kHeightTolerance = 1e-3;        // m
constexpr double kConvergenceTolerance = 0.01;   // deg, spherical formula vs the ellipsoid
constexpr double kPoseTolerance = 0.1;           // m
constexpr double kUtm18CentralMeridian = -75.0;  // deg, EPSG:2959 is NAD83(CSRS) / UTM 18N

// Runs cs2cs (PROJ's command line): map x y z in EPSG:2959 -> WGS84 lat lon h (EPSG:4979).
Eigen::Vector3d Cs2cs(const Eigen::Vector3d& xyz) {
  char command[256];
  std::snprintf(command, sizeof(command),
                "echo '%.6f %.6f %.6f' | cs2cs -f %%.12f EPSG:2959 EPSG:4979", xyz.x(), xyz.y(),
                xyz.z());
  FILE* pipe = popen(command, "r");
  EXPECT_NE(pipe, nullptr);
  char line[256] = {};
  const bool read = pipe && std::fgets(line, sizeof(line), pipe) != nullptr;
  if (pipe) pclose(pipe);
  EXPECT_TRUE(read) << "cs2cs gave no output (is proj-bin installed?)";
  Eigen::Vector3d lat_lon_h = Eigen::Vector3d::Constant(std::nan(""));
  std::istringstream(line) >> lat_lon_h.x() >> lat_lon_h.y() >> lat_lon_h.z();
  return lat_lon_h;
}

class GeoServiceTest : public ::testing::Test {
 protected:
  GeoServiceTest()
      : store_(":memory:"),
        service_(store_, {}),
        runner_("127.0.0.1:0", service_),
        client_(runner_.address()) {}

  storage::SqliteMapStore store_;
  ForestMapService service_;
  ServerRunner runner_;
  client::ForestMapClient client_;
};

TEST_F(GeoServiceTest, UnknownCrsIsRefusedAndNothingIsCreated) {
  try {
    client_.CreateMap("bad", "", "not a crs at all");
    FAIL() << "created a map with a bad CRS";
  } catch (const client::RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(std::string(error.what()).find("crs \"not a crs at all\""), std::string::npos)
        << error.what();
  }
  EXPECT_TRUE(client_.ListMaps().empty());
}

// A map's x and y are metres on a plane: a CRS in degrees or feet would store trees whose
// distances mean nothing to the relocalizer.
TEST_F(GeoServiceTest, CrsInDegreesOrFeetIsRefusedAndNothingIsCreated) {
  try {
    client_.CreateMap("wgs84", "", "EPSG:4326");
    FAIL() << "created a map in degrees";
  } catch (const client::RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::INVALID_ARGUMENT);
    const std::string what = error.what();
    EXPECT_NE(what.find("crs \"EPSG:4326\" (WGS 84) cannot be a map's: it is geographic"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("--to-crs utm"), std::string::npos) << what;
  }
  client::MapTreeRow tree;
  tree.x = 1000000;
  tree.y = 200000;
  try {
    client_.CreateMapWithTrees("feet", "", "EPSG:2263", {tree});
    FAIL() << "created a map in feet";
  } catch (const client::RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(std::string(error.what()).find("US survey foot"), std::string::npos) << error.what();
  }
  EXPECT_TRUE(client_.ListMaps().empty());
}

TEST_F(GeoServiceTest, CrsIsStoredAsEpsgAndDescribedAsWkt) {
  const v1::Map epsg = client_.CreateMap("epsg", "", "EPSG:2959");
  EXPECT_EQ(epsg.crs(), "EPSG:2959");
  EXPECT_EQ(epsg.crs_epsg(), 2959);
  EXPECT_NE(epsg.crs_wkt().find("UTM zone 18N"), std::string::npos) << epsg.crs_wkt();
  // The same CRS as WKT and as a PROJ string.
  const v1::Map wkt = client_.CreateMap("wkt", "", epsg.crs_wkt());
  EXPECT_EQ(wkt.crs(), "EPSG:2959");
  const v1::Map proj = client_.CreateMap("proj", "", "+proj=utm +zone=18 +ellps=GRS80 +units=m");
  EXPECT_FALSE(proj.crs_wkt().empty());
  EXPECT_EQ(client_.GetMap("epsg").crs_epsg(), 2959);
}

TEST_F(GeoServiceTest, RelocalizationOnPrf025AgreesWithCs2cs) {
  if (!std::filesystem::exists(kField)) GTEST_SKIP() << "no " << kField;
  client::TreeFileOptions options;
  options.columns = client::ParseColumnMapping("x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree");
  options.dbh_unit = client::DbhUnit::kCentimetre;
  const auto rows = client::ReadMapTreesCsv(kField, options);
  client_.CreateMap("prf025", "", "EPSG:2959");
  client_.UploadTrees("prf025", rows, false, {});

  // A sensor among the trees, heading 30 deg from grid east, 200 m above the ellipsoid.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& row : rows) centre += Eigen::Vector3d(row.x, row.y, 0) / rows.size();
  Eigen::Isometry3d map_from_sensor = Eigen::Isometry3d::Identity();
  const double yaw = 30.0 * M_PI / 180.0;
  map_from_sensor.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  map_from_sensor.translation() = Eigen::Vector3d(centre.x(), centre.y(), 200.0);
  std::vector<algorithms::DetectedTree> query;
  for (const auto& row : rows) {
    algorithms::DetectedTree tree;
    tree.position = map_from_sensor.inverse() * Eigen::Vector3d(row.x, row.y, 198.7);
    tree.dbh = row.dbh.value_or(algorithms::kUnknown);
    if ((tree.position.head<2>()).norm() < 15.0) query.push_back(tree);
  }
  ASSERT_GE(query.size(), 8u);
  const v1::RelocalizeResponse answer = client_.Relocalize("prf025", query);
  ASSERT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_LOCALIZED) << answer.detail();
  const v1::Vector3& t = answer.map_from_sensor().translation();
  EXPECT_NEAR(t.x(), centre.x(), kPoseTolerance);
  EXPECT_NEAR(t.y(), centre.y(), kPoseTolerance);
  ASSERT_TRUE(answer.has_geodetic());
  const v1::GeodeticPose& g = answer.geodetic();
  const Eigen::Vector3d expected = Cs2cs(Eigen::Vector3d(t.x(), t.y(), t.z()));
  EXPECT_NEAR(g.latitude_deg(), expected.x(), kDegreeTolerance);
  EXPECT_NEAR(g.longitude_deg(), expected.y(), kDegreeTolerance);
  EXPECT_NEAR(g.ellipsoidal_height_m(), expected.z(), kHeightTolerance);
  EXPECT_GT(g.transformation_accuracy_m(), 0);  // NAD83(CSRS) -> WGS 84: PROJ states 1-2 m
  EXPECT_LE(g.transformation_accuracy_m(), 2);
  EXPECT_FALSE(g.ballpark_transformation());
  // Transverse Mercator: grid north is turned from true north by atan(tan(dlon) sin(lat)).
  const double dlon = (g.longitude_deg() - kUtm18CentralMeridian) * M_PI / 180.0;
  const double convergence =
      std::atan(std::tan(dlon) * std::sin(g.latitude_deg() * M_PI / 180.0)) * 180.0 / M_PI;
  EXPECT_NEAR(g.grid_convergence_deg(), convergence, kConvergenceTolerance);
  const double grid_heading = 90.0 - 30.0;
  EXPECT_NEAR(g.true_heading_deg(), grid_heading + convergence, kConvergenceTolerance + 0.05);

  // A tracking session's answers carry the same WGS84 pose.
  client::TrackSession session = client_.Track("prf025");
  client::TrackFrame frame;
  frame.trees = query;
  const v1::TrackResponse tracked = session.Step(frame);
  session.Finish();
  ASSERT_TRUE(tracked.result().has_geodetic());
  EXPECT_NEAR(tracked.result().geodetic().latitude_deg(), expected.x(), kDegreeTolerance);
  EXPECT_NEAR(tracked.result().geodetic().longitude_deg(), expected.y(), kDegreeTolerance);
}

}  // namespace
}  // namespace forestmap::server
