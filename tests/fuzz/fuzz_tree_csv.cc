// libFuzzer target for the tree CSV readers of client/io/tree_csv.h, in memory: each input is
// read as a map file (with default and with explicit column/unit options), a detections file, a
// frames file and a poses file. Bad input must be answered with CsvError; any other exception or
// a sanitizer report is a crash. Accepted rows are checked against the documented contract.
#include <cmath>
#include <cstdint>
#include <string>

#include "client/io/tree_csv.h"

namespace fc = forestmap::client;

namespace {

void Check(bool ok) {
  if (!ok) __builtin_trap();
}

void MapFile(const std::string& text, const fc::TreeFileOptions& options) {
  try {
    for (const fc::MapTreeRow& row : fc::ParseMapTreesCsv(text, "fuzz.csv", options)) {
      Check(std::isfinite(row.x) && std::isfinite(row.y));
      Check(!row.dbh || !std::isinf(*row.dbh));
    }
  } catch (const fc::CsvError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  MapFile(text, {});
  fc::TreeFileOptions mapped;
  mapped.columns = {{"x", "E"}, {"y", "N"}, {"dbh", "BHD"}};
  mapped.dbh_unit = fc::DbhUnit::kCentimetre;
  MapFile(text, mapped);
  try {
    for (const fc::DetectedTreeRow& row : fc::ParseDetectedTreesCsv(text, "fuzz.csv")) {
      Check(std::isfinite(row.tree.position.x()) && std::isfinite(row.tree.position.y()));
    }
  } catch (const fc::CsvError&) {
  }
  try {
    fc::ParseFramesCsv(text, "fuzz.csv");
  } catch (const fc::CsvError&) {
  }
  try {
    for (const auto& [frame, pose] : fc::ParsePosesCsv(text, "fuzz.csv")) {
      Check(pose.translation().allFinite());
    }
  } catch (const fc::CsvError&) {
  }
  return 0;
}
