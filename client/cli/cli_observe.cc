// `forestmap observe NAME --frames trees.csv [--poses poses.csv] [--source ID]
//  [--base-version V --reject-stale] [--batch N] [--from-frame A] [--to-frame B]`:
// adds a drone's per-frame detections to a shared map, in batches of frames (one request and
// one new map version per batch), with progress on stderr and a summary on stdout.

#include <algorithm>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "client/cli/cli_commands.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {
namespace {

// Server limits (observations.proto): 200 frames, 100,000 trees per request.
constexpr int kMaxBatchFrames = 200;
constexpr size_t kMaxBatchTrees = 100'000;

struct ObserveCliOptions {
  std::string map;
  std::string frames_file;
  std::string poses_file;
  std::string source = "forestmap-cli";
  int64_t base_version = 0;
  bool reject_stale = false;
  int batch = 25;  // frames per request
  std::optional<int64_t> from_frame;
  std::optional<int64_t> to_frame;
};

struct Totals {
  int64_t frames = 0, merged = 0, skipped = 0, relocalized = 0;
  int64_t associated = 0, added = 0, promoted = 0;
  std::string first_skip;  // the first reason, for the summary
};

void Count(const v1::ObserveResponse& response, Totals& totals) {
  for (const v1::FrameResult& frame : response.frames()) {
    ++totals.frames;
    if (frame.status() == v1::FrameResult::STATUS_MERGED) {
      ++totals.merged;
    } else {
      ++totals.skipped;
      if (totals.first_skip.empty()) {
        totals.first_skip = "frame " + std::to_string(frame.frame_id()) + ": " + frame.detail();
      }
    }
    totals.relocalized += frame.relocalized() ? 1 : 0;
    totals.associated += frame.trees_associated();
    totals.added += frame.trees_added();
    totals.promoted += frame.trees_promoted();
  }
}

std::vector<ObservedFrame> LoadFrames(const ObserveCliOptions& options) {
  const std::vector<Frame> frames = ReadFramesCsv(options.frames_file);
  std::map<int64_t, algorithms::Pose3> poses;
  if (!options.poses_file.empty()) poses = ReadPosesCsv(options.poses_file);
  std::vector<ObservedFrame> out;
  for (const Frame& frame : frames) {
    if (options.from_frame && frame.frame < *options.from_frame) continue;
    if (options.to_frame && frame.frame > *options.to_frame) continue;
    ObservedFrame observed;
    observed.frame_id = frame.frame;
    observed.trees = frame.trees;
    const auto pose = poses.find(frame.frame);
    if (pose != poses.end()) observed.map_from_sensor = pose->second;
    out.push_back(std::move(observed));
  }
  return out;
}

void RunObserve(const ObserveCliOptions& options, const CliContext& context) {
  const std::vector<ObservedFrame> frames = LoadFrames(options);
  if (frames.empty()) throw CommandError(options.frames_file + ": no frames to observe");
  ForestMapClient client = context.Connect();
  ObserveOptions request_options;
  request_options.source = options.source;
  request_options.base_version = options.base_version;
  request_options.reject_stale = options.reject_stale;
  Totals totals;
  v1::Map map;
  size_t next = 0;
  while (next < frames.size()) {
    std::vector<ObservedFrame> batch;
    size_t trees = 0;
    while (next < frames.size() && static_cast<int>(batch.size()) < options.batch &&
           (batch.empty() || trees + frames[next].trees.size() <= kMaxBatchTrees)) {
      trees += frames[next].trees.size();
      batch.push_back(frames[next++]);
    }
    const v1::ObserveResponse response = client.Observe(options.map, batch, request_options);
    // The next batch builds on the version this one made (a stale check then catches others).
    request_options.base_version = response.map_version();
    map = response.map();
    Count(response, totals);
    *context.err << "observe: " << next << "/" << frames.size() << " frames, map version "
                 << response.map_version() << ", " << map.tree_count() << " trees, "
                 << totals.skipped << " frames skipped" << std::endl;
  }
  *context.out << "observed " << totals.frames << " frames of '" << options.source << "' into map '"
               << options.map << "': " << totals.merged << " merged (" << totals.relocalized
               << " relocalized by the server), " << totals.skipped << " skipped; "
               << totals.associated << " detections associated, " << totals.added
               << " new candidates, " << totals.promoted << " promoted; map version "
               << map.version() << ", " << map.tree_count() << " trees" << std::endl;
  if (!totals.first_skip.empty()) {
    *context.err << "forestmap: note: first skipped " << totals.first_skip << std::endl;
  }
}

}  // namespace

void AddObserveCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<ObserveCliOptions>();
  CLI::App* sub = app.add_subcommand(
      "observe",
      "Add per-frame tree detections (a drone's sequence) to a shared map: each batch of "
      "frames becomes one new map version");
  sub->add_option("NAME", options->map, "Map name")->required();
  sub->add_option("--frames", options->frames_file,
                  "CSV of detections with a frame column: frame,x,y[,z,dbh,axis_x,axis_y,axis_z,"
                  "score] (sensor frame, m)")
      ->required();
  sub->add_option("--poses", options->poses_file,
                  "CSV frame,timestamp,x,y,z,qx,qy,qz,qw: map_from_sensor per frame; frames "
                  "without a pose are relocalized by the server");
  sub->add_option("--source", options->source,
                  "Source (drone) id recorded with every observation: [A-Za-z0-9_.:-]")
      ->capture_default_str();
  sub->add_option("--base-version", options->base_version,
                  "Map version the data builds on (for --reject-stale)")
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--reject-stale", options->reject_stale,
                "Fail (ABORTED) if the map moved past --base-version instead of merging");
  sub->add_option("--batch", options->batch, "Frames per request (one map version each)")
      ->check(CLI::Range(1, kMaxBatchFrames))
      ->capture_default_str();
  sub->add_option("--from-frame", options->from_frame, "Skip frames with a smaller frame number");
  sub->add_option("--to-frame", options->to_frame, "Skip frames with a larger frame number");
  sub->callback([options, &context] {
    if (options->reject_stale && options->base_version == 0) {
      throw CLI::ValidationError("--reject-stale", "needs --base-version");
    }
    context.run = [options, &context] { RunObserve(*options, context); };
  });
}

}  // namespace forestmap::client
