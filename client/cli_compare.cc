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
#include <string>
#include <vector>

#include "algorithms/evaluation/inventory_comparison.h"
#include "client/cli_commands.h"
#include "client/cli_tree_crs.h"
#include "client/cli_tree_input.h"
#include "client/io/las_crs.h"
#include "client/scan_trees.h"

namespace forestmap::client {
namespace {

constexpr double kCm = 100.0;  // cm per m, for the table

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
  std::string links_out;
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
    return {client.ExportTrees(name).trees, client.GetMap(name).crs()};
  }
  if (IsScan(o)) return {DetectInScan(o, context), ReadLasCrs(o.detections)};
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

std::string Id(const MapTreeRow& row, int index) {
  return row.id ? std::to_string(*row.id) : "#" + std::to_string(index + 1);
}

void WriteLinks(const std::string& path, const std::vector<MapTreeRow>& detected,
                const std::vector<algorithms::DetectedTree>& placed,
                const std::vector<MapTreeRow>& reference,
                const algorithms::InventoryComparison& result) {
  std::ofstream out(path);
  out << "detected_id,reference_id,detected_x,detected_y,reference_x,reference_y,distance_m,"
         "detected_dbh_m,reference_dbh_m,dbh_difference_m\n";
  const auto number = [](double v) {
    char text[32];
    std::snprintf(text, sizeof(text), "%.4f", v);
    return std::isfinite(v) ? std::string(text) : std::string();
  };
  for (const algorithms::InventoryLink& link : result.links) {
    const algorithms::DetectedTree& d = placed[link.detected];
    const MapTreeRow& r = reference[link.reference];
    const double reference_dbh = r.dbh.value_or(algorithms::kUnknown);
    out << Id(detected[link.detected], link.detected) << ',' << Id(r, link.reference) << ','
        << number(d.position.x()) << ',' << number(d.position.y()) << ',' << number(r.x) << ','
        << number(r.y) << ',' << number(link.distance) << ',' << number(d.dbh) << ','
        << number(reference_dbh) << ',' << number(d.dbh - reference_dbh) << '\n';
  }
  if (!out) throw CommandError(path + ": cannot write the links");
}

nlohmann::ordered_json ToJson(const algorithms::InventoryComparison& r) {
  nlohmann::ordered_json json;
  json["detected_trees"] = r.detected_trees;
  json["reference_trees"] = r.reference_trees;
  json["linked"] = r.links.size();
  json["completeness"] = r.completeness;
  json["commission"] = r.commission;
  json["position_rmse_m"] = r.position_rmse;
  json["bias_x_m"] = r.bias_x;
  json["bias_y_m"] = r.bias_y;
  json["dbh_pairs"] = r.dbh_pairs;
  json["dbh_rmse_m"] = r.dbh_rmse;
  json["dbh_bias_m"] = r.dbh_bias;
  for (const algorithms::DbhClassOmission& c : r.omission_by_dbh) {
    json["omission_by_dbh"].push_back({{"min_dbh_m", c.min_dbh},
                                       {"max_dbh_m", c.max_dbh},
                                       {"reference_trees", c.reference_trees},
                                       {"linked", c.linked},
                                       {"omission", c.omission}});
  }
  return json;
}

void PrintTable(const CompareOptions& o, const algorithms::InventoryComparison& r,
                std::ostream& out) {
  char line[1024];
  const auto print = [&](const char* format, auto... values) {
    std::snprintf(line, sizeof(line), format, values...);
    out << line << '\n';
  };
  print("%-16s %s (%d trees) vs reference %s (%d trees), links within %.2f m", "compare",
        o.detections.c_str(), r.detected_trees, o.reference.c_str(), r.reference_trees,
        o.comparison.link_distance);
  print("%-16s %zu of %d reference trees", "linked", r.links.size(), r.reference_trees);
  print("%-16s %.1f %%", "completeness", 100 * r.completeness);
  print("%-16s %.1f %% (%d of %d detections unlinked)", "commission", 100 * r.commission,
        r.detected_trees - static_cast<int>(r.links.size()), r.detected_trees);
  print("%-16s %.3f m (bias x %+.3f m, y %+.3f m)", "position RMSE", r.position_rmse, r.bias_x,
        r.bias_y);
  print("%-16s %.2f cm over %d pairs (bias %+.2f cm, detected - reference)", "DBH RMSE",
        kCm * r.dbh_rmse, r.dbh_pairs, kCm * r.dbh_bias);
  out << "omission by reference DBH class:\n";
  print("  %-12s %6s %7s %9s", "DBH cm", "trees", "linked", "omission");
  for (const algorithms::DbhClassOmission& c : r.omission_by_dbh) {
    char range[32];
    std::snprintf(range, sizeof(range), "%.0f-%.0f", kCm * c.min_dbh, kCm * c.max_dbh);
    print("  %-12s %6d %7d %8.1f%%", range, c.reference_trees, c.linked, 100 * c.omission);
  }
}

void Run(const CompareOptions& o, const CliContext& context) {
  // The reference first: its errors come before a scan's detection work.
  TreeFile reference_file =
      ReadTreeFile(o.reference, TreeFileOptionsFrom(o.reference_columns, o.reference_dbh_unit));
  TreeFile detected_file = ReadDetections(o, context);
  AlignCrs(o, detected_file, reference_file, *context.err);
  const std::vector<MapTreeRow>& reference_rows = reference_file.rows;
  const std::vector<MapTreeRow>& detected_rows = detected_file.rows;
  std::vector<algorithms::DetectedTree> detected = AsDetections(detected_rows);
  const std::vector<algorithms::MapTree> reference = ToMapTrees(reference_rows);
  if (o.register_first) {
    const algorithms::Registration registration =
        algorithms::RegisterToReference(detected, reference);
    if (registration.result.status != algorithms::RelocalizeStatus::kLocalized) {
      throw CommandError("--register: the detections were not found in the reference (" +
                         registration.result.detail + ")");
    }
    const algorithms::Pose3& t = registration.reference_from_detected;
    for (algorithms::DetectedTree& tree : detected) tree.position = t * tree.position;
    char text[160];
    std::snprintf(text, sizeof(text),
                  "registered: rotation %.3f deg, translation (%.3f, %.3f) m, %d inliers, "
                  "rmse %.3f m\n",
                  algorithms::YawOf(t.linear()) * 180 / M_PI, t.translation().x(),
                  t.translation().y(), registration.result.inliers, registration.result.rmse);
    *context.err << text;
  }
  const algorithms::InventoryComparison result =
      algorithms::CompareInventories(detected, reference, o.comparison);
  if (!o.links_out.empty())
    WriteLinks(o.links_out, detected_rows, detected, reference_rows, result);
  if (o.json) {
    *context.out << ToJson(result).dump() << std::endl;
  } else {
    PrintTable(o, result, *context.out);
  }
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
      ->check(CLI::PositiveNumber);
  sub->add_option("--dbh-class", o->comparison.dbh_class_width,
                  "Width of the omission DBH classes, m (default 0.1)")
      ->check(CLI::PositiveNumber);
  sub->add_flag("--register", o->register_first,
                "Find the detections in the reference first (relocalizer), for surveys in "
                "different frames");
  sub->add_flag("--json", o->json, "One JSON object instead of the table");
  sub->add_option("--out", o->links_out, "Write the links as CSV");
  sub->callback([o, &context] { context.run = [o, &context] { Run(*o, context); }; });
}

}  // namespace forestmap::client
