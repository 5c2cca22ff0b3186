#include "algorithms/simulation/scanner_model.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "algorithms/core/check.h"

namespace forestmap::algorithms {
namespace {

constexpr double kDeg = M_PI / 180.0;

// `beams` elevations spaced uniformly from +half_fov (ring 0) down to -half_fov.
std::vector<double> UniformElevations(int beams, double half_fov) {
  std::vector<double> elevations(beams);
  for (int i = 0; i < beams; ++i) {
    elevations[i] = half_fov - 2 * half_fov * i / (beams - 1);
  }
  return elevations;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

void ScannerModel::Check() const {
  Require(!beam_elevations.empty(), "ScannerModel.beam_elevations must not be empty", 0);
  for (size_t i = 0; i < beam_elevations.size(); ++i) {
    Require(std::isfinite(beam_elevations[i]) && std::abs(beam_elevations[i]) <= M_PI / 2,
            "ScannerModel.beam_elevations[" + std::to_string(i) + "] must be in [-pi/2, pi/2] rad",
            beam_elevations[i]);
    Require(i == 0 || beam_elevations[i] < beam_elevations[i - 1],
            "ScannerModel.beam_elevations must decrease from ring 0 (the highest beam)",
            beam_elevations[i]);
  }
  Require(columns >= 1, "ScannerModel.columns must be >= 1", columns);
  Require(std::isfinite(azimuth_start), "ScannerModel.azimuth_start must be finite rad",
          azimuth_start);
  Require(std::isfinite(azimuth_step) && azimuth_step != 0,
          "ScannerModel.azimuth_step must be non-zero rad", azimuth_step);
  Require((columns - 1) * std::abs(azimuth_step) < 2 * M_PI + 1e-9,
          "ScannerModel.columns * |azimuth_step| must not exceed 360 deg",
          columns * std::abs(azimuth_step));
  Require(std::isfinite(min_range) && min_range >= 0, "ScannerModel.min_range must be >= 0 m",
          min_range);
  Require(std::isfinite(max_range) && max_range > min_range,
          "ScannerModel.max_range must be finite and > min_range m", max_range);
  Require(std::isfinite(beam_divergence) && beam_divergence >= 0 && beam_divergence < 0.1,
          "ScannerModel.beam_divergence must be in [0, 0.1) rad", beam_divergence);
  Require(std::isfinite(range_noise_sd) && range_noise_sd >= 0,
          "ScannerModel.range_noise_sd must be >= 0 m", range_noise_sd);
}

ScannerModel OusterScanner(OusterFamily family, int beams, int columns) {
  Require(beams == 32 || beams == 64 || beams == 128, "Ouster beams must be 32, 64 or 128", beams);
  Require(columns == 512 || columns == 1024 || columns == 2048,
          "Ouster columns must be 512, 1024 or 2048", columns);
  ScannerModel model;
  double half_fov = 22.5 * kDeg;
  switch (family) {
    case OusterFamily::kOS0:
      model.name = "os0";
      half_fov = 45 * kDeg;
      model.max_range = 50;
      break;
    case OusterFamily::kOS1:
      model.name = "os1";
      break;
    case OusterFamily::kOS2:
      model.name = "os2";
      half_fov = 11.25 * kDeg;
      model.max_range = 240;
      model.beam_divergence = 1.6e-3;
      model.range_noise_sd = 0.02;
      break;
  }
  std::ostringstream name;  // (a stream: GCC 12 warns falsely on "-" + std::string)
  name << model.name << '-' << beams;
  if (columns != 2048) name << '-' << columns;
  model.name = name.str();
  model.beam_elevations = UniformElevations(beams, half_fov);
  model.columns = columns;
  model.azimuth_start = M_PI;  // clockwise from the back, as real Ouster scans
  model.azimuth_step = -2 * M_PI / columns;
  return model;
}

ScannerModel Vlp16Scanner() {
  ScannerModel model;
  model.name = "vlp16";
  model.beam_elevations = UniformElevations(16, 15 * kDeg);  // 2 deg steps
  model.columns = 1800;
  model.azimuth_start = M_PI;  // clockwise, as the sensor spins
  model.azimuth_step = -2 * M_PI / 1800;
  model.min_range = 0.25;
  model.max_range = 100;
  model.beam_divergence = 3.0e-3;
  model.range_noise_sd = 0.015;
  return model;
}

ScannerModel PlanarScanner() {
  ScannerModel model;
  model.name = "planar";
  model.beam_elevations = {0.0};
  model.columns = 1081;  // 270 deg / 0.25 deg + 1
  model.azimuth_start = -135 * kDeg;
  model.azimuth_step = 0.25 * kDeg;
  model.min_range = 0.1;
  model.max_range = 30;
  model.beam_divergence = 1.5e-3;
  model.range_noise_sd = 0.015;
  return model;
}

std::vector<std::string> ScannerPresetNames() {
  return {"os0-32", "os0-64", "os0-128", "os1-32", "os1-64", "os1-128",
          "os2-32", "os2-64", "os2-128", "vlp16",  "planar"};
}

ScannerModel ScannerPreset(const std::string& name) {
  const std::string lower = Lower(name);
  if (lower == "vlp16" || lower == "vlp-16") return Vlp16Scanner();
  if (lower == "planar") return PlanarScanner();
  // osF-B[-C]
  int family = -1, beams = 0, columns = 2048;
  char tail = 0;
  const int fields = std::sscanf(lower.c_str(), "os%d-%d-%d%c", &family, &beams, &columns, &tail);
  const bool ok = (fields == 2 || fields == 3) && family >= 0 && family <= 2 &&
                  (beams == 32 || beams == 64 || beams == 128) &&
                  (columns == 512 || columns == 1024 || columns == 2048);
  if (!ok) {
    std::ostringstream message;
    message << "unknown scanner '" << name << "'; valid:";
    for (const std::string& n : ScannerPresetNames()) message << ' ' << n;
    message << " (Ouster names take an optional -512|-1024|-2048 column suffix)";
    throw std::invalid_argument(message.str());
  }
  return OusterScanner(static_cast<OusterFamily>(family), beams, columns);
}

}  // namespace forestmap::algorithms
