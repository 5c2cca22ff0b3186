#pragma once
// Coordinate reference systems through PROJ (only geo/*.cc include proj.h): parsing and
// validating a CRS given as an EPSG code, WKT or PROJ string, moving points between CRSs, and
// turning map poses into WGS84 latitude, longitude, ellipsoidal height and true heading.
//
// Map frame convention: x east(ing), y north(ing), z up, metres, in the map's projected CRS;
// the CRS's own axis order (some EPSG CRSs are northing-first) is normalised away here.

#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

namespace forestmap::geo {

// A CRS PROJ does not know or cannot use; the message is PROJ's reason, for users.
class CrsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct CrsInfo {
  std::string wkt;   // WKT2:2019
  int epsg = 0;      // the EPSG code it is identical to; 0 when it has none
  std::string name;  // e.g. "NAD83(CSRS) / UTM zone 17N"
  bool projected = false;
  // Why its coordinates cannot be a map's x, y (a plane in metres), for users: e.g. "it is
  // geographic: its coordinates are degrees"; empty when they can (projected or engineering
  // CRSs in metres, alone or with a vertical CRS).
  std::string map_problem;
  // Its area of use (degrees of WGS84 longitude and latitude; west > east when it crosses the
  // antimeridian) and its name; has_area is false when PROJ does not know it.
  bool has_area = false;
  double west = 0, south = 0, east = 0, north = 0;
  std::string area;
  // Whether a point (degrees) lies in the area of use widened by `margin_deg`; true without one.
  bool InArea(double longitude_deg, double latitude_deg, double margin_deg) const;
  // How to store it: "EPSG:n" when it has an EPSG code, else the WKT.
  std::string Canonical() const;
};

// Parses `text` ("EPSG:2959", WKT, "+proj=utm +zone=17 ..."); throws CrsError. Results are
// cached (PROJ's database look-ups take milliseconds). Thread-safe.
CrsInfo ParseCrs(const std::string& text);

// Moves points from one CRS to another with PROJ's best transformation for each point, as cs2cs
// does; coordinates in easting, northing (longitude, latitude) order whatever the CRSs' axis
// orders. Thread-safe (PROJ objects are used under a lock).
class Reprojection {
 public:
  Reprojection(const std::string& from, const std::string& to);  // throws CrsError
  ~Reprojection();
  Reprojection(const Reprojection&) = delete;
  Reprojection& operator=(const Reprojection&) = delete;

  // What PROJ used for the last point: its stated accuracy and whether it is a ballpark (no
  // datum or height transformation known: errors of metres).
  struct Used {
    double accuracy_m = -1;  // -1: PROJ states none
    bool ballpark = false;
  };

  // x, y, z in place (z passes unchanged between 2-D CRSs); throws CrsError when PROJ cannot
  // transform the point (outside the CRSs' domain). `used`, when given, says what moved it.
  void Apply(double& x, double& y, double& z, Used* used = nullptr) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  mutable std::mutex mutex_;
};

// Map units per metre on the ground (the WGS84 ellipsoid) at (x, y) of `crs`, eastwards: 1.0004
// near a UTM zone's edge, 1.44 for Web Mercator (EPSG:3857) at 46 degrees of latitude. Throws
// CrsError when PROJ cannot place the point on the Earth (a local grid, a point off the CRS).
double GridScaleAt(const std::string& crs, double x, double y);

// "EPSG:326zz" (north) or "EPSG:327zz" (south): the WGS 84 / UTM zone of a point (degrees).
// Throws CrsError for a latitude outside UTM's [-80, 84] or a non-finite point.
std::string UtmZoneCrs(double longitude_deg, double latitude_deg);

// The WGS84 pose of a sensor.
struct GeodeticPose {
  double latitude_deg = 0;            // WGS84 (EPSG:4979)
  double longitude_deg = 0;           // WGS84, east positive
  double ellipsoidal_height_m = 0;    // above the WGS84 ellipsoid (map z taken as ellipsoidal)
  double true_heading_deg = 0;        // of the sensor's x axis, clockwise from true north, [0, 360)
  double grid_convergence_deg = 0;    // true heading minus grid heading (clockwise from grid north)
  Reprojection::Used transformation;  // map CRS -> WGS84: PROJ's stated accuracy, ballpark
};

// Map CRS -> WGS84 (EPSG:4979) with PROJ's best transformation for each point, as cs2cs does.
// Thread-safe (PROJ objects are used under a lock).
class MapToWgs84 {
 public:
  explicit MapToWgs84(const std::string& crs);  // throws CrsError

  // A position (map x, y, z in metres) and the sensor's grid heading (yaw, radians counter-
  // clockwise from map x). Throws CrsError when PROJ cannot transform the point.
  GeodeticPose Convert(double x, double y, double z, double yaw_rad) const;

 private:
  Reprojection to_wgs84_;
};

}  // namespace forestmap::geo
