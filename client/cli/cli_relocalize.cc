// `forestmap relocalize NAME --trees FILE [--prior X,Y,RADIUS_M]`,
// `forestmap relocalize NAME --scan SCAN [--prior ...]` (trunks detected here, on the client) and
// `forestmap relocalize NAME --frames FILE`; instead of NAME a set of maps, `--maps A,B,C`,
// `--maps-matching GLOB` or `--all-maps` (the answer names the map found in).

#include <algorithm>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "client/cli/cli_commands.h"
#include "client/cli/cli_format.h"
#include "client/io/tree_csv.h"
#include "client/lib/scan_trees.h"

namespace forestmap::client {
namespace {

constexpr int kProgressEveryFrames = 50;

struct RelocalizeOptions {
  MapSelection maps;  // NAME, or --maps / --maps-matching / --all-maps
  std::string trees_file;
  std::string frames_file;
  std::string scan_file;
  std::string prior_text;
  std::optional<PriorPosition> prior;  // parsed from prior_text
  std::vector<double> gravity_values;
  std::optional<Eigen::Vector3d> gravity;  // down, sensor frame (the drone's IMU)
};

void PrintLine(const CliContext& context, const v1::RelocalizeResponse& response,
               std::optional<int64_t> frame) {
  *context.out << RelocalizeJson(response, frame).dump() << std::endl;
}

void RunSingle(const RelocalizeOptions& options, const CliContext& context) {
  const std::vector<DetectedTreeRow> rows = ReadDetectedTreesCsv(options.trees_file);
  if (rows.empty()) throw CommandError(options.trees_file + ": no trees (header only)");
  std::set<int64_t> frames;
  std::vector<algorithms::DetectedTree> trees;
  trees.reserve(rows.size());
  for (const DetectedTreeRow& row : rows) {
    if (row.frame) frames.insert(*row.frame);
    trees.push_back(row.tree);
  }
  if (frames.size() > 1) {
    throw CommandError(options.trees_file + " holds the trees of " + std::to_string(frames.size()) +
                       " frames; use --frames to relocalize each frame");
  }
  PrintLine(context,
            context.Connect().Relocalize(options.maps, trees, options.prior, options.gravity), {});
}

// Detects the trunks of one scan here, then asks the server: what the drone's thin client does.
void RunScan(const RelocalizeOptions& options, const CliContext& context) {
  const ScanTrees scan = DetectScanTrees(options.scan_file);
  char ms[32];
  std::snprintf(ms, sizeof ms, "%.1f", scan.stats.total_us / 1000.0);
  *context.err << "relocalize: " << options.scan_file << ": " << scan.stats.input_points
               << " points, " << scan.trees.size() << " trees detected in " << ms << " ms"
               << std::endl;
  PrintLine(context,
            context.Connect().Relocalize(options.maps, scan.trees, options.prior, options.gravity),
            {});
}

struct FrameCounts {
  int localized = 0, ambiguous = 0, not_found = 0, failed = 0;
  std::vector<double> server_ms;

  void Add(const v1::RelocalizeResponse& response) {
    localized += response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED;
    ambiguous += response.status() == v1::RelocalizeResponse::STATUS_AMBIGUOUS;
    not_found += response.status() == v1::RelocalizeResponse::STATUS_NOT_FOUND;
    server_ms.push_back(response.server_time_ms());
  }
  std::string Describe() const {
    return std::to_string(localized) + " localized, " + std::to_string(ambiguous) + " ambiguous, " +
           std::to_string(not_found) + " not_found" +
           (failed > 0 ? ", " + std::to_string(failed) + " failed" : "");
  }
  double MedianServerMs() {
    if (server_ms.empty()) return 0;
    auto middle = server_ms.begin() + static_cast<long>(server_ms.size() / 2);
    std::nth_element(server_ms.begin(), middle, server_ms.end());
    return *middle;
  }
};

// One request per frame. A frame the server rejects as invalid (too few trees, ...) is a warning
// and the run goes on; any other error (unreachable server, unknown map) ends it.
void RunFrames(const RelocalizeOptions& options, const CliContext& context) {
  const std::vector<Frame> frames = ReadFramesCsv(options.frames_file);
  if (frames.empty()) throw CommandError(options.frames_file + ": no frames (header only)");
  ForestMapClient client = context.Connect();
  FrameCounts counts;
  for (size_t i = 0; i < frames.size(); ++i) {
    const Frame& frame = frames[i];
    try {
      const v1::RelocalizeResponse response = client.Relocalize(options.maps, frame.trees);
      counts.Add(response);
      PrintLine(context, response, frame.frame);
    } catch (const RpcError& error) {
      if (error.code() != grpc::StatusCode::INVALID_ARGUMENT) throw;
      ++counts.failed;
      *context.err << "forestmap: warning: frame " << frame.frame << ": " << error.what()
                   << std::endl;
    }
    if ((i + 1) % kProgressEveryFrames == 0 && i + 1 < frames.size()) {
      *context.err << "relocalize: " << i + 1 << "/" << frames.size()
                   << " frames: " << counts.Describe() << std::endl;
    }
  }
  char median[32];
  std::snprintf(median, sizeof(median), "%.1f", counts.MedianServerMs());
  *context.err << "relocalize: " << frames.size() << " frames: " << counts.Describe()
               << "; median server time " << median << " ms";
  if (client.retries() > 0) {
    *context.err << "; " << client.retries() << " calls retried on another replica (now "
                 << client.current_address() << ")";
  }
  *context.err << std::endl;
  if (counts.failed > 0) {
    throw CommandError(std::to_string(counts.failed) + " of " + std::to_string(frames.size()) +
                       " frames were rejected by the server (see the warnings above)");
  }
}

// --prior X,Y,RADIUS_M, parsed; a CLI11 error naming the flag otherwise.
PriorPosition PriorFlag(const std::string& text) {
  try {
    return ParsePrior(text);
  } catch (const std::invalid_argument& error) {
    throw CLI::ValidationError("--prior", error.what());
  }
}

// --gravity GX,GY,GZ as a unit vector; a CLI11 error for a zero or non-finite one.
Eigen::Vector3d GravityFlag(const std::vector<double>& values) {
  const Eigen::Vector3d g(values[0], values[1], values[2]);
  if (!g.allFinite() || g.norm() < 1e-6) {
    throw CLI::ValidationError("--gravity", "needs a finite, non-zero vector GX,GY,GZ");
  }
  return g.normalized();
}

}  // namespace

std::function<void()> AddMapSelection(CLI::App& command, MapSelection& maps) {
  CLI::Option* name = command.add_option("NAME", maps.name, "Map name");
  CLI::Option* names =
      command
          .add_option("--maps", maps.names,
                      "Instead of NAME: these maps (A,B,C), in one question; each answer names "
                      "the map the sensor is in (\"map\")")
          ->delimiter(',');
  CLI::Option* pattern = command.add_option(
      "--maps-matching", maps.name_pattern,
      "Instead of NAME: the maps whose name matches this glob ('district-*') among those the "
      "token may read");
  CLI::Option* all = command.add_flag("--all-maps", maps.all_readable,
                                      "Instead of NAME: every map the token may read");
  for (CLI::Option* set : {names, pattern, all}) set->excludes(name);
  names->excludes(pattern)->excludes(all);
  pattern->excludes(all);
  return [name, names, pattern, all] {
    if (name->count() + names->count() + pattern->count() + all->count() == 0) {
      throw CLI::RequiredError("NAME, --maps, --maps-matching or --all-maps");
    }
  };
}

void AddRelocalizeCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<RelocalizeOptions>();
  CLI::App* sub = app.add_subcommand(
      "relocalize",
      "Find the sensor pose in a map from the trees it detected; prints one JSON line per query");
  const std::function<void()> check_maps = AddMapSelection(*sub, options->maps);
  CLI::Option* trees = sub->add_option(
      "--trees", options->trees_file,
      "CSV of the trees detected in one scan, sensor frame: x,y (m) required; z, dbh (m), score, "
      "axis_x,axis_y,axis_z optional");
  CLI::Option* frames =
      sub->add_option("--frames", options->frames_file,
                      "CSV of many scans with a frame column (frame,x,y,...): one query per frame");
  CLI::Option* prior = sub->add_option(
      "--prior", options->prior_text,
      "Prior position X,Y,RADIUS_M: the sensor is within RADIUS_M of (X,Y) (map frame, m); "
      "X,Y,YAW_DEG,RADIUS_M of older versions is accepted too (the heading bounds nothing: the "
      "search covers every heading)");
  CLI::Option* scan = sub->add_option("--scan", options->scan_file,
                                      "LiDAR scan in the sensor frame (.pcd .ply .las .csv .xyz): "
                                      "trunks are detected here and "
                                      "only the tree list is sent")
                          ->check(CLI::ExistingFile);
  CLI::Option* gravity =
      sub->add_option("--gravity", options->gravity_values,
                      "GX,GY,GZ: direction of gravity (down) in the sensor frame, e.g. from the "
                      "drone's IMU; without it roll and pitch come from the stems' axes")
          ->delimiter(',')
          ->expected(3);
  gravity->excludes(frames);
  trees->excludes(frames);
  scan->excludes(trees);
  scan->excludes(frames);
  prior->excludes(frames);
  sub->callback([options, check_maps, trees, frames, scan, prior, gravity, &context] {
    check_maps();
    if (trees->count() + frames->count() + scan->count() == 0) {
      throw CLI::RequiredError("--trees FILE, --scan SCAN or --frames FILE");
    }
    if (prior->count() > 0) options->prior = PriorFlag(options->prior_text);
    if (gravity->count() > 0) options->gravity = GravityFlag(options->gravity_values);
    context.run = [options, &context] {
      if (!options->scan_file.empty()) {
        RunScan(*options, context);
      } else if (options->frames_file.empty()) {
        RunSingle(*options, context);
      } else {
        RunFrames(*options, context);
      }
    };
  });
}

}  // namespace forestmap::client
