#pragma once
// What `forestmap compare` prints and writes (cli_compare.cc): the table, the JSON object and
// the links CSV. A figure over nothing (no links, no DBH pairs, no reference trees) is "-" in the
// table and null in the JSON, never 0.

#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/evaluation/inventory_comparison.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {

// The --register transform, when there was one.
// The shift is given about the reference's centre (the mean of its trees), where a reader can
// judge it: how far the detections there move. The translation is the same transform's about
// the coordinates' origin (a UTM origin is hundreds of km away), for machines.
struct CompareRegistration {
  double rotation_deg = 0;   // yaw, reference from detected
  double centre_x = 0;       // m, the reference's centre
  double centre_y = 0;       // m
  double shift_x = 0;        // m, of the detections at the centre
  double shift_y = 0;        // m
  double translation_x = 0;  // m, reference_from_detected's, about the origin
  double translation_y = 0;  // m
  int inliers = 0;           // trees the relocalizer matched
  double rmse = 0;           // m, of those matches
};

// Everything a report shows.
struct CompareReport {
  std::string detections, reference;  // file names as given
  double link_distance = 0;           // m
  algorithms::InventoryComparison result;
  std::optional<algorithms::SubsetCompleteness> visible;  // reference has a `visible` column
  std::optional<CompareRegistration> registration;        // --register
};

nlohmann::ordered_json CompareJson(const CompareReport& report);
void PrintCompareTable(const CompareReport& report, std::ostream& out);

// --out: one row per link (ids are the files' own, text ids included, else #ROW).
void WriteCompareLinks(const std::string& path, const std::vector<MapTreeRow>& detected,
                       const std::vector<algorithms::DetectedTree>& placed,
                       const std::vector<MapTreeRow>& reference,
                       const algorithms::InventoryComparison& result);

// --out-unlinked: status,id,x,y,dbh_m; one row per reference tree no detection is linked to
// (status missed), then one per detection linked to nothing (status commission).
void WriteCompareUnlinked(const std::string& path, const std::vector<MapTreeRow>& detected,
                          const std::vector<algorithms::DetectedTree>& placed,
                          const std::vector<MapTreeRow>& reference,
                          const algorithms::InventoryComparison& result);

// The text id of a row: its `id`, else the text id the file had (kept as an attribute when not
// an integer, tree_csv.h), else "#N" (its 1-based row).
std::string RowId(const MapTreeRow& row, int index);

}  // namespace forestmap::client
