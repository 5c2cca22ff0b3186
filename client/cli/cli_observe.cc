// `forestmap observe NAME --frames trees.csv [--poses poses.csv] [--source ID]
//  [--base-version V --reject-stale] [--batch N] [--from-frame A] [--to-frame B]
//  [--pose-sigma M] [--yaw-sigma DEG] [--sensor-range M] [--detection-probability P]`:
// adds a drone's per-frame detections to a shared map, in batches of frames (one request and
// one new map version per batch), with progress on stderr and a summary on stdout. A pose
// without detections is a frame that saw no tree (evidence of absence).

#include <algorithm>
#include <cmath>
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
  double pose_sigma = 0;  // m
  double yaw_sigma = 0;   // degrees
  double sensor_range = 0;
  double detection_probability = 0;
  bool merge_only = false;
};

struct Totals {
  int64_t frames = 0, merged = 0, skipped = 0, relocalized = 0;
  int64_t associated = 0, added = 0, promoted = 0, missed = 0, removed = 0;
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
    totals.missed += frame.trees_missed();
    totals.removed += frame.trees_removed();
  }
}

std::vector<ObservedFrame> LoadFrames(const ObserveCliOptions& options) {
  const std::vector<Frame> frames = ReadFramesCsv(options.frames_file);
  std::map<int64_t, algorithms::Pose3> poses;
  if (!options.poses_file.empty()) poses = ReadPosesCsv(options.poses_file);
  // Frames by number: those with detections, and the poses of frames that detected nothing.
  std::map<int64_t, ObservedFrame> by_id;
  for (const Frame& frame : frames) by_id[frame.frame].trees = frame.trees;
  for (const auto& [id, pose] : poses) by_id[id].map_from_sensor = pose;
  std::vector<ObservedFrame> out;
  for (auto& [id, observed] : by_id) {
    if (options.from_frame && id < *options.from_frame) continue;
    if (options.to_frame && id > *options.to_frame) continue;
    observed.frame_id = id;
    observed.position_sigma = options.pose_sigma;
    observed.yaw_sigma = options.yaw_sigma * M_PI / 180;
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
  request_options.sensor_range = options.sensor_range;
  request_options.detection_probability = options.detection_probability;
  request_options.merge_only = options.merge_only;
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
                 << totals.skipped << " frames skipped, server " << response.server_time_ms()
                 << " ms" << std::endl;
  }
  *context.out << "observed " << totals.frames << " frames of '" << options.source << "' into map '"
               << options.map << "': " << totals.merged << " merged (" << totals.relocalized
               << " relocalized by the server), " << totals.skipped << " skipped; "
               << totals.associated << " detections associated, " << totals.added
               << " new candidates, " << totals.promoted << " promoted; " << totals.missed
               << " map trees missed, " << totals.removed << " trees removed; map version "
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
  sub->add_option("--pose-sigma", options->pose_sigma,
                  "1-sigma horizontal error of the poses (m, per axis; 0: exact)")
      ->check(CLI::Range(0.0, 1000.0));
  sub->add_option("--yaw-sigma", options->yaw_sigma,
                  "1-sigma heading error of the poses (degrees; 0: exact)")
      ->check(CLI::Range(0.0, 180.0));
  sub->add_option("--sensor-range", options->sensor_range,
                  "Horizontal range (m) within which the sensor detects trunks, for the evidence "
                  "that trees are gone (0: learned from the frames)")
      ->check(CLI::Range(0.0, 1000.0));
  sub->add_option("--detection-probability", options->detection_probability,
                  "Probability that the sensor detects an unhidden trunk near it, in [0, 1) (0: "
                  "learned from the frames)")
      ->check(CLI::Range(0.0, 0.999));
  sub->add_flag("--merge-only", options->merge_only,
                "Merge the detections without weighing what the frames did not see (frames that "
                "do not list every trunk the sensor detected): removes no tree");
  sub->callback([options, &context] {
    if (options->reject_stale && options->base_version == 0) {
      throw CLI::ValidationError("--reject-stale", "needs --base-version");
    }
    context.run = [options, &context] { RunObserve(*options, context); };
  });
}

}  // namespace forestmap::client
