// forestmap-lab bench-mapping: building tree maps from frame sequences, in process, against truth.
//
// Survey merge:  --frames F --poses P --use-poses --map map.csv
//   merges every frame with its ground-truth pose (algorithms/merging/map_merge.h), rebuilds the
//   map from the set of observations as forestmapd holds it (algorithms::RebuildTrees: any order or
//   batching of the uploads gives this map) and compares the confirmed trees with the reference map
//   (algorithms/evaluation/map_evaluation.h).
// Mapping:       --frames F --poses P [--eval-frames F2 --eval-poses P2 --truth-offset ...]
//   builds the map from the detections alone (algorithms/mapping/map_builder.h; poses only score
//   it): the trajectory's ATE after a planar rigid and a planar similarity alignment to P, then the
//   built map moved into P's world frame with the similarity (--rigid: the rigid) alignment and
//   the frames of F2 (poses P2, moved by --truth-offset) relocalized against it, scored like
//   bench-reloc. The scale is there because the ground truth of Wild_V01/V02 is 0.12% larger
//   than the geometry of the detected stems (a map built from them cannot know that).
// --out writes the built (or merged) confirmed trees as a map CSV (map frame; with --align-out
// in the world frame of P). --trajectory-out writes every frame's estimated pose (aligned to P),
// its true pose and how it was fixed, for diagnosis.

#include <chrono>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "algorithms/evaluation/map_evaluation.h"
#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/mapping/map_builder.h"
#include "algorithms/merging/merged_map.h"
#include "algorithms/relocalization/relocalizer.h"
#include "client/io/tree_csv.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

using algorithms::Pose3;

struct BenchMappingOptions {
  std::string frames_path, poses_path, map_path, eval_frames_path, eval_poses_path, out_path;
  std::string trajectory_path;
  std::vector<double> truth_offset;  // x, y, z (m), yaw (deg): map_from_world of eval poses
  bool use_poses = false;
  bool align_out = false;
  bool no_loops = false;
  bool rigid = false;
  int step = 1, limit = 0, eval_step = 1;
  bool json = false;
};

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

struct Sequence {
  std::vector<Frame> frames;  // the chosen frames, in order
  std::vector<Pose3> truth;   // world_from_sensor of each
};

Sequence ReadSequence(const std::string& frames_path, const std::string& poses_path, int step,
                      int limit) {
  const auto poses = ReadPosesCsv(poses_path);
  auto frames = ReadFramesCsv(frames_path);
  Sequence sequence;
  for (size_t i = 0; i < frames.size(); i += step) {
    if (limit > 0 && sequence.frames.size() >= static_cast<size_t>(limit)) break;
    const auto pose = poses.find(frames[i].frame);
    if (pose == poses.end()) {
      throw CommandError(poses_path + ": no pose for frame " + std::to_string(frames[i].frame) +
                         " of " + frames_path);
    }
    sequence.truth.push_back(pose->second);
    sequence.frames.push_back(std::move(frames[i]));
  }
  if (sequence.frames.empty()) throw CommandError(frames_path + ": no frames");
  return sequence;
}

void WriteTrees(const std::string& path, const std::vector<algorithms::MapTree>& trees) {
  std::vector<MapTreeRow> rows;
  for (const algorithms::MapTree& tree : trees) {
    MapTreeRow row;
    row.id = tree.id;
    row.x = tree.position.x();
    row.y = tree.position.y();
    if (algorithms::IsKnown(tree.position.z())) row.z = tree.position.z();
    if (algorithms::IsKnown(tree.dbh)) row.dbh = tree.dbh;
    rows.push_back(row);
  }
  WriteMapTreesCsv(path, rows);
}

nlohmann::ordered_json CompareJson(const algorithms::TreeMapComparison& c) {
  return {{"reference_trees", c.reference_trees},
          {"confirmed_trees", c.built_trees},
          {"found", c.found},
          {"found_fraction", c.found_fraction},
          {"distance_p50_m", c.distance_p50},
          {"distance_p95_m", c.distance_p95},
          {"dbh_abs_diff_p50_m", c.dbh_abs_diff_p50},
          {"close_pairs", c.close_pairs},
          {"duplicates", c.duplicates},
          {"unmatched_confirmed", c.unmatched_built}};
}

nlohmann::ordered_json SurveyMerge(const BenchMappingOptions& o, std::ostream& err) {
  const Sequence sequence = ReadSequence(o.frames_path, o.poses_path, o.step, o.limit);
  const auto start = std::chrono::steady_clock::now();
  algorithms::MergedMap map;
  for (size_t i = 0; i < sequence.frames.size(); ++i) {
    algorithms::FrameObservations frame;
    frame.source = o.frames_path;
    frame.frame_id = sequence.frames[i].frame;
    frame.map_from_sensor = sequence.truth[i];
    frame.trees = sequence.frames[i].trees;
    map.Merge(frame);
    LabProgress(err, "bench-mapping merge", i + 1, sequence.frames.size(), 100);
  }
  const double merge_s = Seconds(start);
  const algorithms::ConsolidateResult consolidated = map.Rebuild();
  nlohmann::ordered_json report = {{"mode", "survey_merge"},
                                   {"frames", sequence.frames.size()},
                                   {"observations", map.observations().size()},
                                   {"trees", map.size()},
                                   {"merged_duplicates", consolidated.merged},
                                   {"merge_s", merge_s},
                                   {"total_s", Seconds(start)}};
  if (!o.map_path.empty()) {
    const auto reference = ToMapTrees(ReadMapTreesCsv(o.map_path));
    report.update(CompareJson(algorithms::CompareTreeMaps(map.ConfirmedMapTrees(), reference)));
  }
  if (!o.out_path.empty()) WriteTrees(o.out_path, map.ConfirmedMapTrees());
  return report;
}

// Relocalizes the evaluation frames against the built map (moved into the truth's world frame).
void Relocalize(const BenchMappingOptions& o, const std::vector<algorithms::MapTree>& map,
                nlohmann::ordered_json& report, std::ostream& err) {
  const Sequence eval = ReadSequence(o.eval_frames_path, o.eval_poses_path, o.eval_step, 0);
  Pose3 map_from_world = Pose3::Identity();
  if (!o.truth_offset.empty()) {
    map_from_world = algorithms::PoseFromXyzYaw(o.truth_offset[0], o.truth_offset[1],
                                                o.truth_offset[2], o.truth_offset[3] * M_PI / 180);
  }
  err << "bench-mapping: building the index of the " << map.size() << " trees mapped" << std::endl;
  const algorithms::MapIndex index(map);
  algorithms::RelocEvaluator evaluator(map);
  for (size_t i = 0; i < eval.frames.size(); ++i) {
    const Pose3 truth = map_from_world * eval.truth[i];
    algorithms::RelocalizeQuery query;
    query.trees = eval.frames[i].trees;
    const auto start = std::chrono::steady_clock::now();
    const algorithms::RelocalizeResult result = algorithms::Relocalize(index, query);
    evaluator.Add(evaluator.Answerable(query.trees, truth), truth, result, Seconds(start) * 1e3);
    LabProgress(err, "bench-mapping relocalize", i + 1, eval.frames.size(), 100);
  }
  const algorithms::RelocSummary s = evaluator.Summary();
  report["eval_frames"] = s.frames;
  report["eval_answerable"] = s.answerable;
  report["reloc_recall"] = s.recall;
  report["reloc_strict_recall"] = s.strict_recall;
  report["reloc_wrong"] = s.wrong;
  report["reloc_error_xy_p50_m"] = s.error_xy_p50;
}

// The built trajectory against the truth, frame by frame, in the truth's world frame (by
// `alignment`): CSV frame,fix,x,y,z,yaw,true_x,...,error_xy,error_z (m, rad).
void WriteTrajectory(const std::string& path, const Sequence& sequence,
                     const std::vector<Pose3>& poses, const std::vector<algorithms::FrameFix>& how,
                     const algorithms::TrajectoryError& alignment) {
  std::ofstream out(path);
  out << "frame,fix,x,y,z,yaw,true_x,true_y,true_z,true_yaw,error_xy,error_z\n";
  for (size_t i = 0; i < poses.size(); ++i) {
    const Pose3 estimate = alignment.truth_from_estimate * poses[i];
    const Eigen::Vector3d e = alignment.ToTruth(poses[i].translation());
    const Eigen::Vector3d t = sequence.truth[i].translation();
    const auto yaw = [](const Pose3& p) { return std::atan2(p(1, 0), p(0, 0)); };
    out << sequence.frames[i].frame << "," << algorithms::ToString(how[i]) << "," << e.x() << ","
        << e.y() << "," << e.z() << "," << yaw(estimate) << "," << t.x() << "," << t.y() << ","
        << t.z() << "," << yaw(sequence.truth[i]) << "," << (e - t).head<2>().norm() << ","
        << e.z() - t.z() << "\n";
  }
  if (!out) throw CommandError(path + ": cannot write");
}

nlohmann::ordered_json BuildMap(const BenchMappingOptions& o, std::ostream& err) {
  const Sequence sequence = ReadSequence(o.frames_path, o.poses_path, o.step, o.limit);
  algorithms::MapBuilderOptions options;
  options.loop_closure = !o.no_loops;
  algorithms::MapBuilder builder(options);
  int fixes[5] = {0, 0, 0, 0, 0};
  std::vector<algorithms::FrameFix> how;
  const auto start = std::chrono::steady_clock::now();
  for (size_t i = 0; i < sequence.frames.size(); ++i) {
    algorithms::BuilderFrame frame;
    frame.frame_id = sequence.frames[i].frame;
    frame.trees = sequence.frames[i].trees;
    how.push_back(builder.AddFrame(frame).fix);
    ++fixes[static_cast<int>(how.back())];
    LabProgress(err, "bench-mapping build", i + 1, sequence.frames.size(), 100);
  }
  builder.Finish();
  const double build_s = Seconds(start);
  const std::vector<Pose3> poses = builder.Poses();
  using algorithms::Alignment;
  const algorithms::TrajectoryError planar =
      algorithms::CompareTrajectories(poses, sequence.truth, Alignment::kPlanar);
  const algorithms::TrajectoryError similar =
      algorithms::CompareTrajectories(poses, sequence.truth, Alignment::kPlanarSimilarity);
  const algorithms::TrajectoryError full = algorithms::CompareTrajectories(poses, sequence.truth);
  // The built map in the truth's world frame, by the chosen alignment of the trajectory.
  const algorithms::TrajectoryError& alignment = o.rigid ? planar : similar;
  std::vector<algorithms::MapTree> aligned = builder.ConfirmedTrees();
  for (algorithms::MapTree& tree : aligned) tree.position = alignment.ToTruth(tree.position);
  nlohmann::ordered_json report = {{"mode", "build"},
                                   {"frames", sequence.frames.size()},
                                   {"fixes_tracked", fixes[1]},
                                   {"fixes_relocalized", fixes[2]},
                                   {"fixes_global", fixes[3]},
                                   {"dead_reckoned", fixes[4]},
                                   {"loop_closures", builder.loop_closures()},
                                   {"confirmed_trees", aligned.size()},
                                   {"ate_xy_rmse_m", planar.ate_rmse},
                                   {"ate_xy_p50_m", planar.ate_p50},
                                   {"ate_xy_max_m", planar.ate_max},
                                   {"ate_xy_similarity_rmse_m", similar.ate_rmse},
                                   {"ate_xy_similarity_max_m", similar.ate_max},
                                   {"truth_scale", similar.scale},
                                   {"ate_3d_rmse_m", full.ate_rmse},
                                   {"eval_alignment", o.rigid ? "planar" : "planar_similarity"},
                                   {"build_s", build_s}};
  if (!o.map_path.empty()) {
    const auto reference = ToMapTrees(ReadMapTreesCsv(o.map_path));
    report["map_vs_reference"] = CompareJson(algorithms::CompareTreeMaps(aligned, reference));
  }
  if (!o.eval_frames_path.empty()) Relocalize(o, aligned, report, err);
  if (!o.out_path.empty()) WriteTrees(o.out_path, o.align_out ? aligned : builder.ConfirmedTrees());
  if (!o.trajectory_path.empty())
    WriteTrajectory(o.trajectory_path, sequence, poses, how, alignment);
  return report;
}

}  // namespace

void AddBenchMappingCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<BenchMappingOptions>();
  CLI::App* cmd = app.add_subcommand(
      "bench-mapping",
      "Build tree maps from frame sequences in process and score them against ground truth: "
      "merge with known poses (--use-poses) or map without poses (ATE, relocalization recall)");
  cmd->add_option("--frames", options->frames_path, "Frames CSV (frame,x,y,z,...), sensor frame")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--poses", options->poses_path,
                  "Ground-truth poses CSV of --frames (frame,timestamp,x,y,z,qx,qy,qz,qw)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_flag("--use-poses", options->use_poses,
                "Merge the frames with their ground-truth poses (survey merge)");
  cmd->add_option("--map", options->map_path, "Reference map CSV to compare the trees with")
      ->check(CLI::ExistingFile);
  cmd->add_option("--eval-frames", options->eval_frames_path,
                  "Frames to relocalize against the built map")
      ->check(CLI::ExistingFile);
  cmd->add_option("--eval-poses", options->eval_poses_path, "Ground-truth poses of --eval-frames")
      ->check(CLI::ExistingFile);
  cmd->add_option("--truth-offset", options->truth_offset,
                  "X,Y,Z,YAW_DEG: world_of_poses_from_world_of_eval_poses (session offset)")
      ->delimiter(',')
      ->expected(4);
  cmd->add_option("--step", options->step, "Use every N-th frame")->check(CLI::PositiveNumber);
  cmd->add_option("--limit", options->limit, "At most N frames (0 = all)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--eval-step", options->eval_step, "Relocalize every N-th evaluation frame")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--no-loops", options->no_loops, "Build without loop closure");
  cmd->add_flag(
      "--rigid", options->rigid,
      "Move the built map into the truth's frame without a scale (default: with the "
      "trajectory's horizontal scale, as the truth's scale may differ from the sensor's)");
  cmd->add_option("--out", options->out_path, "Write the confirmed trees to this map CSV");
  cmd->add_option("--trajectory-out", options->trajectory_path,
                  "Write each frame's estimated (aligned) and true pose to this CSV");
  cmd->add_flag("--align-out", options->align_out,
                "Write the built map in the world frame of --poses (after the alignment)");
  cmd->add_flag("--json", options->json, "Print one JSON object");
  cmd->callback([options, &context] {
    if (options->eval_frames_path.empty() != options->eval_poses_path.empty()) {
      throw CLI::ValidationError("--eval-frames", "needs --eval-poses (and the reverse)");
    }
    if (options->use_poses && !options->eval_frames_path.empty()) {
      throw CLI::ValidationError("--eval-frames", "is for mapping without --use-poses");
    }
    context.run = [options, &context] {
      const nlohmann::ordered_json report = options->use_poses ? SurveyMerge(*options, *context.err)
                                                               : BuildMap(*options, *context.err);
      if (options->json) {
        *context.out << report.dump() << "\n";
        return;
      }
      for (const auto& [key, value] : report.items()) *context.out << key << ": " << value << "\n";
    };
  });
}

}  // namespace forestmap::client
