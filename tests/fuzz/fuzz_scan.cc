// libFuzzer target for one scan format of client/io (FORESTMAP_FUZZ_EXTENSION, set by
// tests/fuzz/CMakeLists.txt: .pcd, .ply, .las or .csv). The readers take paths (PCL reads only
// files), so each input is written to a temporary file with that extension and read through
// ReadScan, the entry point the CLI uses. A reader must answer bad bytes with ScanError; any other
// exception, a sanitizer report or a cloud whose arrays disagree is a crash.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "client/io/scan_io.h"

namespace {

// /dev/shm when there is one (no disk writes per input), else the temporary directory.
std::string TempPath() {
  std::filesystem::path dir = "/dev/shm";
  std::error_code error;
  if (!std::filesystem::is_directory(dir, error)) dir = std::filesystem::temp_directory_path();
  return (dir / ("forestmap_fuzz_" + std::to_string(getpid()) + FORESTMAP_FUZZ_EXTENSION)).string();
}

const std::string& InputPath() {
  static const std::string path = [] {
    std::string p = TempPath();
    std::atexit([] { std::remove(InputPath().c_str()); });
    return p;
  }();
  return path;
}

void CheckCloud(const forestmap::algorithms::PointCloud& cloud) {
  const bool consistent =
      static_cast<uint64_t>(cloud.width) * cloud.height == cloud.points.size() &&
      (cloud.intensity.empty() || cloud.intensity.size() == cloud.points.size()) &&
      (cloud.ring.empty() || cloud.ring.size() == cloud.points.size());
  if (!consistent) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = InputPath();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!out) std::abort();
  }
  for (const bool keep_invalid : {false, true}) {
    forestmap::client::ScanReadOptions options;
    options.keep_invalid_points = keep_invalid;
    try {
      CheckCloud(forestmap::client::ReadScan(path, options));
    } catch (const forestmap::client::ScanError&) {
    }
  }
  if (std::string(FORESTMAP_FUZZ_EXTENSION) == ".csv") {  // the planar scan reader too
    try {
      const forestmap::algorithms::PlanarScan scan = forestmap::client::ReadPlanarScan(path);
      if (scan.angles.size() != scan.ranges.size()) __builtin_trap();
    } catch (const forestmap::client::ScanError&) {
    }
  }
  return 0;
}
