// `forestmap track NAME --frames FILE [--odometry POSES]`: one tracking session (the Track RPC)
// driven from a file of frames, in frame order. Prints one JSON line per frame and a summary.
// Instead of NAME a set of maps (--maps, --maps-matching, --all-maps): the session crosses from
// one map into the next, each line naming its map.

#include <algorithm>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "client/cli/cli_commands.h"
#include "client/cli/cli_format.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {
namespace {

constexpr int kTrackProgressEveryFrames = 200;

struct TrackOptions {
  MapSelection maps;  // NAME, or --maps / --maps-matching / --all-maps
  std::string frames_file;
  std::string odometry_file;
};

const char* StateName(v1::TrackResponse::State state) {
  switch (state) {
    case v1::TrackResponse::STATE_TRACKING:
      return "tracking";
    case v1::TrackResponse::STATE_RECOVERED:
      return "recovered";
    case v1::TrackResponse::STATE_LOST:
      return "lost";
    default:
      return "unspecified";
  }
}

const char* MethodName(v1::TrackResponse::Method method) {
  switch (method) {
    case v1::TrackResponse::METHOD_LOCAL:
      return "local";
    case v1::TrackResponse::METHOD_PRIOR:
      return "prior";
    case v1::TrackResponse::METHOD_GLOBAL:
      return "global";
    default:
      return "unspecified";
  }
}

void Run(const TrackOptions& options, const CliContext& context) {
  const std::vector<Frame> frames = ReadFramesCsv(options.frames_file);
  if (frames.empty()) throw CommandError(options.frames_file + ": no frames (header only)");
  OdometryFromPoses odometry(options.odometry_file);

  ForestMapClient client = context.Connect();
  TrackSession session = client.Track(options.maps);
  int counts[4] = {0, 0, 0, 0};  // by TrackResponse::State
  int longest_loss = 0;
  std::vector<double> server_ms;
  for (size_t i = 0; i < frames.size(); ++i) {
    TrackFrame frame;
    frame.frame_id = frames[i].frame;
    frame.trees = frames[i].trees;
    frame.odometry = odometry.Next(frame.frame_id);

    const v1::TrackResponse response = session.Step(frame);
    ++counts[std::clamp<int>(response.state(), 0, 3)];
    longest_loss = std::max(longest_loss, response.frames_lost());
    server_ms.push_back(response.result().server_time_ms());
    nlohmann::ordered_json line = RelocalizeJson(response.result(), response.frame_id());
    line["state"] = StateName(response.state());
    line["method"] = MethodName(response.method());
    line["frames_lost"] = response.frames_lost();
    *context.out << line.dump() << "\n";
    if ((i + 1) % kTrackProgressEveryFrames == 0 && i + 1 < frames.size()) {
      *context.err << "track: " << i + 1 << "/" << frames.size() << " frames\n";
    }
  }
  session.Finish();
  char times[96];
  std::snprintf(times, sizeof times, "server time p50 %.2f ms, p95 %.2f ms",
                algorithms::Percentile(server_ms, 0.5), algorithms::Percentile(server_ms, 0.95));
  *context.err << "track: " << frames.size()
               << " frames: " << counts[v1::TrackResponse::STATE_TRACKING] << " tracking, "
               << counts[v1::TrackResponse::STATE_RECOVERED] << " recovered, "
               << counts[v1::TrackResponse::STATE_LOST] << " lost (longest loss " << longest_loss
               << " frames); " << times << std::endl;
}

}  // namespace

void AddTrackCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<TrackOptions>();
  CLI::App* sub = app.add_subcommand(
      "track",
      "Track a drone through a map frame by frame (one tracking session); prints one JSON line "
      "per frame with its state (tracking, recovered, lost)");
  const std::function<void()> check_maps = AddMapSelection(*sub, options->maps);
  sub->add_option("--frames", options->frames_file,
                  "CSV of the scans' trees with a frame column (frame,x,y,...), sensor frame, "
                  "sent in file order")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--odometry", options->odometry_file,
                  "Poses CSV (frame,timestamp,x,y,z,qx,qy,qz,qw) in any world frame: the motion "
                  "between consecutive frames is sent as odometry")
      ->check(CLI::ExistingFile);
  sub->callback([options, check_maps, &context] {
    check_maps();
    context.run = [options, &context] { Run(*options, context); };
  });
}

}  // namespace forestmap::client
