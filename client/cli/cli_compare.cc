// `forestmap compare DETECTIONS --reference INVENTORY`: detected trees (a tree file, a map, or a
// scan whose trunks are detected here) against a reference inventory
// (algorithms/inventory_comparison.h), optionally registered first.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/evaluation/inventory_comparison.h"
#include "client/cli/cli_commands.h"
#include "client/cli/cli_compare_report.h"
#include "client/cli/cli_tree_crs.h"
#include "client/cli/cli_tree_input.h"
#include "client/io/file_replace.h"
#include "client/io/las_crs.h"
#include "client/lib/scan_trees.h"

namespace forestmap::client {
namespace {

constexpr double kMinLinkDistance = 0.01;  // m: closer than a stem's width is no link distance
constexpr double kMinDbhClass = 0.01;      // m: DBH is measured to the cm

struct CompareOptions {
  std::string detections;   // tree file, map:NAME, or a scan (trunks detected here)
  bool scan = false;        // DETECTIONS is a scan whatever its extension (.csv / .txt point lists)
  bool multi_view = false;  // the scan is merged from many viewpoints (as detect --multi-view)
  std::string reference;
  std::string columns, dbh_unit;                      // of the detections
  std::string reference_columns, reference_dbh_unit;  // of the reference
  algorithms::InventoryComparisonOptions comparison;
  bool register_first = false;
  bool json = false;
  std::string links_out;       // --out: the links as CSV
  std::string unlinked_out;    // --out-unlinked: missed reference trees and unlinked detections
  std::string registered_out;  // --registered-out: the detections moved into the reference
};

// Point clouds by extension; a .csv or .txt is a tree file unless --scan says it is a scan.
bool IsScan(const CompareOptions& o) {
  std::string extension = std::filesystem::path(o.detections).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return o.scan || extension == ".pcd" || extension == ".ply" || extension == ".las" ||
         extension == ".laz" || extension == ".xyz";
}

// The trunks of a scan, found as `forestmap detect` finds them, in the scan file's frame.
std::vector<MapTreeRow> DetectInScan(const CompareOptions& o, const CliContext& context) {
  ScanDetection scan;
  try {
    scan = DetectTrunksInScan(o.detections, {}, o.multi_view);
  } catch (const std::invalid_argument& error) {
    throw CommandError(error.what());
  }
  std::vector<MapTreeRow> rows;
  for (const algorithms::DetectedTrunk& trunk : scan.result.trees) {
    MapTreeRow& row = rows.emplace_back();
    const Eigen::Vector3d position = trunk.tree.position + scan.origin;
    row.x = position.x();
    row.y = position.y();
    row.z = position.z();
    if (algorithms::IsKnown(trunk.tree.dbh)) row.dbh = trunk.tree.dbh;
  }
  char ms[32];
  std::snprintf(ms, sizeof(ms), "%.1f", scan.result.stats.total_us / 1000.0);
  *context.err << o.detections << ": " << scan.result.stats.input_points << " points, "
               << rows.size() << " trunks detected in " << ms << " ms" << std::endl;
  return rows;
}

// The detections and the CRS they are in ("" when unknown).
TreeFile ReadDetections(const CompareOptions& o, const CliContext& context) {
  const std::string prefix = "map:";
  if (o.detections.rfind(prefix, 0) == 0) {
    const std::string name = o.detections.substr(prefix.size());
    ForestMapClient client = context.Connect();
    ExportedTrees exported = client.ExportTrees(name);
    return {std::move(exported.trees), client.GetMap(name).crs(),
            std::move(exported.attribute_columns)};
  }
  if (IsScan(o)) return {DetectInScan(o, context), ReadLasCrs(o.detections), {}};
  return ReadTreeFile(o.detections, TreeFileOptionsFrom(o.columns, o.dbh_unit));
}

// Both inventories in one CRS in metres, when they declare their CRSs: the reference's, or the
// UTM zone of the reference when it is in degrees or feet. One without a CRS is taken to be in
// the other's.
void AlignCrs(const CompareOptions& o, TreeFile& detected, TreeFile& reference, std::ostream& log) {
  if (!InMetres(reference.crs)) {
    reference.crs = ReprojectTrees(reference.rows, o.reference, reference.crs, "utm", log);
  }
  if (detected.crs.empty()) return;
  const std::string target =
      reference.crs.empty() ? (InMetres(detected.crs) ? "" : "utm") : reference.crs;
  if (target.empty() || (target != "utm" && SameCrs(target, detected.crs))) return;
  detected.crs = ReprojectTrees(detected.rows, o.detections, detected.crs, target, log);
}

std::vector<algorithms::DetectedTree> AsDetections(const std::vector<MapTreeRow>& rows) {
  std::vector<algorithms::DetectedTree> trees;
  for (const MapTreeRow& row : rows) {
    algorithms::DetectedTree tree;
    tree.position = Eigen::Vector3d(row.x, row.y, row.z.value_or(0.0));
    tree.dbh = row.dbh.value_or(algorithms::kUnknown);
    trees.push_back(tree);
  }
  return trees;
}

// The reference's `visible` column (0/1, as `simulate` writes it), when it has one.
std::optional<std::vector<bool>> VisibleColumn(const std::vector<MapTreeRow>& rows,
                                               const std::string& path) {
  constexpr const char* kVisible = "visible";
  if (rows.empty() || !rows.front().attributes.count(kVisible)) return std::nullopt;
  std::vector<bool> visible;
  for (size_t i = 0; i < rows.size(); ++i) {
    const auto it = rows[i].attributes.find(kVisible);
    const std::string value = it == rows[i].attributes.end() ? "" : it->second;
    if (value != "0" && value != "1") {
      throw CommandError(path + ": tree " + std::to_string(i + 1) + ": column 'visible' is '" +
                         value + "', not 0 or 1");
    }
    visible.push_back(value == "1");
  }
  return visible;
}

// The relocalizer's answer in words for two inventories (its own speaks of a drone and a map).
std::string RegistrationFailure(const algorithms::RelocalizeResult& result) {
  std::string detail = result.detail;
  const std::string drone = "; is the drone in this map?";
  if (const size_t at = detail.find(drone); at != std::string::npos) detail.erase(at);
  return "--register: the detections could not be placed in the reference (" + detail +
         "); do the two inventories cover the same trees (at least a few dozen in common)? "
         "Without --register they are compared in the coordinates they have";
}

// The detections' rows with their positions moved into the reference's frame (`registered`),
// as CSV with the reference's CRS beside it.
void WriteRegistered(const std::string& path, std::vector<MapTreeRow> rows,
                     const std::vector<algorithms::DetectedTree>& registered,
                     const std::string& crs) {
  for (size_t i = 0; i < rows.size(); ++i) {
    rows[i].x = registered[i].position.x();
    rows[i].y = registered[i].position.y();
    if (rows[i].z) rows[i].z = registered[i].position.z();
  }
  ReplaceFile(path, [&](const std::string& temporary) { WriteMapTreesCsv(temporary, rows); });
  WriteCrsSidecar(path, crs);
}

// Moves `detected` into the reference's frame; throws CommandError when it cannot.
CompareRegistration Register(std::vector<algorithms::DetectedTree>& detected,
                             const std::vector<algorithms::MapTree>& reference, std::ostream& log) {
  const algorithms::Registration registration =
      algorithms::RegisterToReference(detected, reference);
  if (registration.result.status != algorithms::RelocalizeStatus::kLocalized) {
    throw CommandError(RegistrationFailure(registration.result));
  }
  const algorithms::Pose3& t = registration.reference_from_detected;
  for (algorithms::DetectedTree& tree : detected) tree.position = t * tree.position;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const algorithms::MapTree& tree : reference) {
    centre += Eigen::Vector3d(tree.position.x(), tree.position.y(), 0);
  }
  centre /= static_cast<double>(std::max<size_t>(1, reference.size()));
  // p' - c = R (p - c) + shift: the shift is what the transform does at the centre.
  const Eigen::Vector3d shift = t * centre - centre;
  CompareRegistration out;
  out.rotation_deg = algorithms::YawOf(t.linear()) * 180 / M_PI;
  out.centre_x = centre.x();
  out.centre_y = centre.y();
  out.shift_x = shift.x();
  out.shift_y = shift.y();
  out.translation_x = t.translation().x();
  out.translation_y = t.translation().y();
  out.inliers = registration.result.inliers;
  out.rmse = registration.result.rmse;
  char text[200];
  std::snprintf(text, sizeof(text),
                "registered: rotation %.3f deg and shift (%.3f, %.3f) m about the reference's "
                "centre (%.1f, %.1f), %d inliers, rmse %.3f m\n",
                out.rotation_deg, out.shift_x, out.shift_y, out.centre_x, out.centre_y, out.inliers,
                out.rmse);
  log << text;
  return out;
}

void Run(const CompareOptions& o, const CliContext& context) {
  // The reference first: its errors come before a scan's detection work.
  TreeFile reference_file = ReadTreeFile(
      o.reference,
      TreeFileOptionsFrom(o.reference_columns, o.reference_dbh_unit, "", "--reference-"));
  TreeFile detected_file = ReadDetections(o, context);
  AlignCrs(o, detected_file, reference_file, *context.err);
  const std::vector<MapTreeRow>& reference_rows = reference_file.rows;
  const std::vector<MapTreeRow>& detected_rows = detected_file.rows;
  std::vector<algorithms::DetectedTree> detected = AsDetections(detected_rows);
  const std::vector<algorithms::MapTree> reference = ToMapTrees(reference_rows);
  CompareReport report{o.detections, o.reference, o.comparison.link_distance, {}, {}, {}};
  if (!o.registered_out.empty()) {
    if (!o.register_first) throw CommandError("--registered-out needs --register");
    CheckNoSidecarClash(o.registered_out, TreeFormat::kCsv);
  }
  if (o.register_first) report.registration = Register(detected, reference, *context.err);
  if (!o.registered_out.empty()) {
    WriteRegistered(o.registered_out, detected_rows, detected, reference_file.crs);
  }
  report.result = algorithms::CompareInventories(detected, reference, o.comparison);
  if (const auto visible = VisibleColumn(reference_rows, o.reference)) {
    report.visible = algorithms::CompletenessOver(report.result, *visible);
  }
  if (!o.links_out.empty()) {
    WriteCompareLinks(o.links_out, detected_rows, detected, reference_rows, report.result);
  }
  if (!o.unlinked_out.empty()) {
    WriteCompareUnlinked(o.unlinked_out, detected_rows, detected, reference_rows, report.result);
  }
  if (o.json) {
    *context.out << CompareJson(report).dump() << std::endl;
  } else {
    PrintCompareTable(report, *context.out);
  }
}

// Refuses lengths under `min` (m) with a message naming the flag, in plain numbers.
CLI::Validator AtLeast(double min, const std::string& what) {
  return CLI::Validator(
      [min, what](std::string& text) -> std::string {
        double value = 0;
        try {
          size_t used = 0;
          value = std::stod(text, &used);
          if (used != text.size()) return "'" + text + "' is not a number of metres";
        } catch (const std::exception&) {
          return "'" + text + "' is not a number of metres";
        }
        if (!(value >= min)) {
          char limit[32];
          std::snprintf(limit, sizeof(limit), "%g", min);
          return text + " m is too small: " + what + " is at least " + limit + " m";
        }
        return "";
      },
      "METRES");
}

}  // namespace

void AddCompareCommand(CLI::App& app, CliContext& context) {
  auto o = std::make_shared<CompareOptions>();
  CLI::App* sub = app.add_subcommand(
      "compare",
      "Compare detected trees with a reference inventory: one-to-one links, completeness, "
      "commission, position and DBH RMSE and bias, omission by DBH class");
  sub->add_option("DETECTIONS", o->detections,
                  "Detected trees: a tree file (CSV, .gpkg, .geojson, .shp), map:NAME, or a scan "
                  "(.pcd .ply .las .xyz; trunks detected here as `detect` does)")
      ->required();
  sub->add_flag("--scan", o->scan,
                "DETECTIONS is a scan even with a .csv / .txt extension (a point list)");
  sub->add_flag("--multi-view", o->multi_view,
                "The scan is merged from many viewpoints (as detect --multi-view)");
  sub->add_option("--reference", o->reference, "Reference inventory (a tree file)")->required();
  AddTreeFileOptions(*sub, o->columns, o->dbh_unit);
  sub->add_option("--reference-columns", o->reference_columns, "--columns of the reference");
  sub->add_option("--reference-dbh-unit", o->reference_dbh_unit, "--dbh-unit of the reference");
  sub->add_option("--link-distance", o->comparison.link_distance,
                  "Largest distance of a link, m (default 0.8)")
      ->check(AtLeast(kMinLinkDistance, "a link distance"));
  sub->add_option("--dbh-class", o->comparison.dbh_class_width,
                  "Width of the omission DBH classes, m (default 0.1)")
      ->check(AtLeast(kMinDbhClass, "a DBH class"));
  sub->add_flag("--register", o->register_first,
                "Find the detections in the reference first (relocalizer), for surveys in "
                "different frames");
  sub->add_flag("--json", o->json, "One JSON object instead of the table");
  sub->add_option("--out", o->links_out, "Write the links as CSV");
  sub->add_option("--out-unlinked", o->unlinked_out,
                  "Write the trees without a link as CSV (status,id,x,y,dbh_m): missed reference "
                  "trees, then unlinked detections (status commission)");
  sub->add_option("--registered-out", o->registered_out,
                  "With --register: write the detections moved into the reference's "
                  "coordinates as CSV (the reference's CRS in a .prj beside it)");
  sub->callback([o, &context] { context.run = [o, &context] { Run(*o, context); }; });
}

}  // namespace forestmap::client
