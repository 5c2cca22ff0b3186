#pragma once
// Beam patterns of the LiDAR scanners the scan simulator (algorithms/simulation/scan_simulation.h)
// models.
//
// A scanner fires `rings` beams (one per elevation) in each of `columns` azimuth steps. In the
// SENSOR frame (x forward, y left, z up; geometry.h) beam (ring, column) points along
//   (cos(el) cos(az), cos(el) sin(az), sin(el)),
//   el = beam_elevations[ring], az = azimuth_start + column * azimuth_step.
// One convention for every preset: ring 0 is the HIGHEST beam (Ouster's order, and the row order
// of an organised cloud: row = ring, points[ring * columns + column]). Note that real Velodyne
// drivers number rings from the lowest beam up; the simulator does not copy that.
// Spinning presets turn clockwise seen from above, as the real sensors do: column 0 looks
// backwards (az = 180 deg) and az decreases by 360 deg / columns per column, so column
// columns / 2 looks along +x (checked against the real organised OS1-64 scans in
// shared/data/scans/sloam_uav_ouster). The planar preset sweeps counter-clockwise.
//
// Presets (datasheet values, rounded):
//   Ouster OS0 / OS1 / OS2, 32 / 64 / 128 beams, 512 / 1024 / 2048 columns, uniform beam spacing
//     over a vertical field of view of +-45 / +-22.5 / +-11.25 deg; max range 50 / 120 / 240 m,
//     min range 0.25 m, beam divergence 3.1 / 3.1 / 1.6 mrad, range noise sd 0.015 / 0.015 /
//     0.02 m. OS1-64 x 2048 is the default drone scanner (the sloam_uav_ouster data's sensor).
//   Velodyne VLP-16: -15..15 deg in 2 deg steps, 1800 columns (0.2 deg at 10 Hz), 100 m,
//     3.0 mrad, 0.015 m.
//   Planar: a Hokuyo UTM-30LX-like 2-D scanner: 270 deg field of view (-135..135 deg) in
//     0.25 deg steps (1081 beams), 30 m, 0.1 m min range, 1.5 mrad, sd 0.015 m.

#include <cmath>
#include <string>
#include <vector>

namespace forestmap::algorithms {

struct ScannerModel {
  std::string name = "os1-64";             // preset name, for file names and messages
  std::vector<double> beam_elevations;     // rad, one per ring, ring 0 = highest
  int columns = 2048;                      // azimuth steps per scan
  double azimuth_start = M_PI;             // rad, azimuth of column 0
  double azimuth_step = -2 * M_PI / 2048;  // rad, non-zero; < 0 = clockwise
  double min_range = 0.25;                 // m, nearer hits give no return
  double max_range = 120;                  // m, farther hits give no return
  double beam_divergence = 3.1e-3;         // rad, full angle of the beam footprint
  double range_noise_sd = 0.015;           // m, Gaussian range noise (1 sigma)

  int rings() const { return static_cast<int>(beam_elevations.size()); }
  bool IsPlanar() const { return rings() == 1; }
  double Azimuth(int column) const { return azimuth_start + column * azimuth_step; }
  // Throws std::invalid_argument naming the field (no beams, non-finite or unsorted elevations,
  // a field of view over 360 deg, non-positive ranges or steps, negative noise).
  void Check() const;
};

enum class OusterFamily { kOS0, kOS1, kOS2 };

// Ouster-style scanner: beams in {32, 64, 128}, columns in {512, 1024, 2048}, uniform spacing.
// Throws std::invalid_argument for other counts.
ScannerModel OusterScanner(OusterFamily family, int beams, int columns);
ScannerModel Vlp16Scanner();
ScannerModel PlanarScanner();

// By name, case-insensitive: "os0-32|64|128", "os1-32|64|128", "os2-32|64|128" (2048 columns;
// "os1-64-1024" style suffixes choose the columns), "vlp16", "planar". The default is
// "os1-64". Throws std::invalid_argument listing the valid names.
ScannerModel ScannerPreset(const std::string& name);
// The names ScannerPreset accepts without a column suffix, for --help texts.
std::vector<std::string> ScannerPresetNames();

}  // namespace forestmap::algorithms
