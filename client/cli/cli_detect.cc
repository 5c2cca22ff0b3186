// `forestmap detect SCAN [--out trees.csv] [--format csv|json]`: trunk detection in one scan.
//
// The CSV has the columns of a detections file (x,y,z,dbh,score,axis_x,axis_y,axis_z; see
// client/io/tree_csv.h), so `forestmap relocalize MAP --trees trees.csv` reads it, followed by the
// detector's diagnostics. Positions are in the scan's frame with its origin added back (full
// georeferenced coordinates for clouds that had an offset subtracted). The summary line on stderr
// gives the per-stage counts and times.

#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "algorithms/detection/trunk_detection.h"
#include "client/cli/cli_commands.h"
#include "client/cli/cli_tree_input.h"
#include "client/io/las_crs.h"
#include "client/io/scan_io.h"
#include "client/lib/scan_trees.h"

namespace forestmap::client {
namespace {

struct DetectCommandOptions {
  std::string scan;
  std::string out;
  std::string format = "csv";
  bool multi_view = false;
  double beam_divergence = 0;
  double min_height = algorithms::StemLayerOptions().min_height;
  double max_height = algorithms::StemLayerOptions().max_height;
  uint32_t seed = 1;
  algorithms::StemModelOptions stem;  // defaults, for the tuning flags below
};

std::string Number(double value, int decimals) {
  if (!std::isfinite(value)) return "";
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

void WriteCsv(std::ostream& out, const algorithms::TrunkDetectionResult& result,
              const Eigen::Vector3d& origin) {
  out << "x,y,z,dbh,score,axis_x,axis_y,axis_z,bh_x,bh_y,bh_z,ground_known,points,slices,"
         "residual,arc_coverage,range\n";
  for (const algorithms::DetectedTrunk& t : result.trees) {
    const Eigen::Vector3d p = t.tree.position + origin;
    const Eigen::Vector3d bh = t.breast_height_point + origin;
    out << Number(p.x(), 4) << ',' << Number(p.y(), 4) << ',' << Number(p.z(), 4) << ','
        << Number(t.tree.dbh, 4) << ',' << Number(t.tree.score, 3) << ','
        << Number(t.tree.axis.x(), 4) << ',' << Number(t.tree.axis.y(), 4) << ','
        << Number(t.tree.axis.z(), 4) << ',' << Number(bh.x(), 4) << ',' << Number(bh.y(), 4) << ','
        << Number(bh.z(), 4) << ',' << (t.ground_known ? 1 : 0) << ',' << t.points_used << ','
        << t.slices << ',' << Number(t.residual, 4) << ',' << Number(t.arc_coverage, 3) << ','
        << Number(t.range, 3) << '\n';
  }
}

nlohmann::json ToJson(const algorithms::TrunkDetectionResult& result,
                      const Eigen::Vector3d& origin) {
  nlohmann::json trees = nlohmann::json::array();
  auto vec = [](const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  for (const algorithms::DetectedTrunk& t : result.trees) {
    trees.push_back({{"position", vec(t.tree.position + origin)},
                     {"dbh", t.tree.dbh},
                     {"axis", vec(t.tree.axis)},
                     {"score", t.tree.score},
                     {"breast_height_point", vec(t.breast_height_point + origin)},
                     {"ground_known", t.ground_known},
                     {"points", t.points_used},
                     {"slices", t.slices},
                     {"residual", t.residual},
                     {"arc_coverage", t.arc_coverage},
                     {"range", t.range}});
  }
  const algorithms::TrunkDetectionStats& s = result.stats;
  return {{"trees", trees},
          {"ground_known", result.ground_known},
          {"stats",
           {{"input_points", s.input_points},
            {"valid_points", s.valid_points},
            {"ground_points", s.ground_points},
            {"stem_layer_points", s.stem_layer_points},
            {"clusters", s.clusters},
            {"candidates", s.candidates},
            {"trees", s.trees},
            {"total_us", s.total_us}}},
          {"rejected",
           {{"slices", result.stem_stats.rejected_slices},
            {"tilt", result.stem_stats.rejected_tilt},
            {"residual", result.stem_stats.rejected_residual},
            {"coverage", result.stem_stats.rejected_coverage},
            {"dbh", result.stem_stats.rejected_dbh},
            {"score", result.stem_stats.rejected_score},
            {"duplicates", result.stem_stats.duplicates}}}};
}

std::string Summary(const std::string& scan, const algorithms::TrunkDetectionResult& result) {
  const algorithms::TrunkDetectionStats& s = result.stats;
  auto ms = [](int64_t us) { return Number(us / 1000.0, 1); };
  std::ostringstream line;
  line << scan << ": " << s.input_points << " points (" << s.valid_points << " valid), "
       << s.ground_points << " ground" << (result.ground_known ? "" : " (ground unknown)") << ", "
       << s.stem_layer_points << " in stem layer, " << s.clusters << " clusters, " << s.candidates
       << " candidates, " << s.trees << " trees; ms: filter " << ms(s.filter_us) << ", ground "
       << ms(s.ground_us) << ", layer " << ms(s.layer_us) << ", cluster " << ms(s.cluster_us)
       << ", fit " << ms(s.fit_us) << ", total " << ms(s.total_us);
  return line.str();
}

void Run(const DetectCommandOptions& options, const CliContext& context) {
  algorithms::TrunkDetectionOptions detection;
  detection.layer.min_height = options.min_height;
  detection.layer.max_height = options.max_height;
  detection.stem = options.stem;
  detection.stem.beam_divergence = options.beam_divergence;
  detection.stem.seed = options.seed;
  ScanDetection scan;
  try {
    scan = DetectTrunksInScan(options.scan, detection, options.multi_view);
  } catch (const std::invalid_argument& error) {
    throw CommandError(error.what());
  }
  const algorithms::TrunkDetectionResult& result = scan.result;
  const Eigen::Vector3d& origin = scan.origin;
  std::ostringstream text;
  const std::string crs = ReadLasCrs(options.scan);  // "" unless a LAS file declares one
  if (options.format == "json") {
    nlohmann::json json = ToJson(result, origin);
    if (!crs.empty()) json["crs"] = crs;
    text << json.dump(2) << '\n';
  } else {
    WriteCsv(text, result, origin);
  }
  if (options.out.empty() || options.out == "-") {
    *context.out << text.str() << std::flush;
  } else {
    if (options.format != "json") CheckNoSidecarClash(options.out, TreeFormat::kCsv);
    std::ofstream file(options.out);
    file << text.str();
    file.close();
    if (!file) throw CommandError(options.out + ": cannot write the tree list");
    // The CRS beside a CSV, as GIS tools keep it (map create --trees reads it back); none: an
    // old .prj is removed.
    if (options.format != "json") WriteCrsSidecar(options.out, crs);
  }
  if (!crs.empty()) *context.err << options.scan << ": CRS " << ShortCrs(crs) << std::endl;
  *context.err << Summary(options.scan, result) << std::endl;
}

}  // namespace

void AddDetectCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<DetectCommandOptions>();
  CLI::App* command = app.add_subcommand(
      "detect",
      "Detect tree trunks in a LiDAR scan (.pcd .ply .las .csv .xyz .txt) and write the tree "
      "list (position = stem-ground intersection, DBH at 1.3 m), readable by `relocalize "
      "--trees`");
  command->add_option("scan", options->scan, "Scan file")->required()->check(CLI::ExistingFile);
  command->add_option("--out,-o", options->out, "Output file (default: standard output)");
  command->add_option("--format", options->format, "Output format")
      ->check(CLI::IsMember({"csv", "json"}))
      ->capture_default_str();
  command->add_flag("--multi-view", options->multi_view,
                    "The cloud is merged from many viewpoints (no sensor at the origin); "
                    "implied for georeferenced clouds");
  command
      ->add_option("--beam-divergence", options->beam_divergence,
                   "Full beam divergence in rad for the DBH edge-bias compensation "
                   "(Ouster OS1: 0.0031); 0 = off")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--min-height", options->min_height, "Stem layer bottom, m above ground")
      ->capture_default_str();
  command->add_option("--max-height", options->max_height, "Stem layer top, m above ground")
      ->capture_default_str();
  command->add_option("--seed", options->seed, "RANSAC seed")->capture_default_str();
  command->add_option("--slice-height", options->stem.slice_height, "Stem slice height, m")
      ->capture_default_str();
  command
      ->add_option("--inlier-distance", options->stem.circle.inlier_distance,
                   "Circle fit inlier distance, m")
      ->capture_default_str();
  command->callback(
      [options, &context] { context.run = [options, &context] { Run(*options, context); }; });
}

}  // namespace forestmap::client
