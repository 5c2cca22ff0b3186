#include "server/app/absence_ledger.h"

#include <algorithm>
#include <nlohmann/json.hpp>
#include <tuple>
#include <utility>

#include "server/app/tree_records.h"

namespace forestmap::server {
namespace {

using nlohmann::json;

json GroupsJson(const algorithms::TreeEvidence& evidence) {
  json groups = json::array();
  for (const algorithms::GroupMisses& g : evidence.groups) {
    groups.push_back(json::array({g.group, g.misses, g.log_all_missed}));
  }
  return groups;
}

}  // namespace

algorithms::TreeEvidence ToTreeEvidence(const storage::TreeRecord& tree) {
  algorithms::TreeEvidence evidence;
  if (tree.last_seen_unix_ms) evidence.last_seen = *tree.last_seen_unix_ms;
  if (!tree.evidence) return evidence;
  // Written by SetEvidence; anything else (a hand-edited database) reads as no misses.
  const json stored = json::parse(*tree.evidence, nullptr, /*allow_exceptions=*/false);
  if (!stored.is_object()) return evidence;
  try {
    evidence.sightings = stored.value("sightings", 0);
    evidence.misses = stored.value("misses", 0);
    evidence.last_seen_group = stored.value("seen_by", std::string());
    for (const json& g : stored.value("groups", json::array())) {
      evidence.groups.push_back(
          {g.at(0).get<std::string>(), g.at(2).get<double>(), g.at(1).get<int>()});
    }
  } catch (const json::exception&) {
    evidence.groups.clear();
    evidence.misses = 0;
  }
  return evidence;
}

void SetEvidence(storage::TreeRecord& tree, const algorithms::TreeEvidence& evidence) {
  tree.last_seen_unix_ms.reset();
  if (evidence.last_seen != algorithms::kNeverSeen) tree.last_seen_unix_ms = evidence.last_seen;
  tree.evidence.reset();
  if (evidence.sightings == 0 && evidence.groups.empty()) return;
  json stored = {{"sightings", evidence.sightings}, {"misses", evidence.misses}};
  if (!evidence.last_seen_group.empty()) stored["seen_by"] = evidence.last_seen_group;
  if (!evidence.groups.empty()) stored["groups"] = GroupsJson(evidence);
  tree.evidence = stored.dump();
}

AbsenceLedger::AbsenceLedger(std::string source, int64_t time_unix_ms, AbsenceSettings settings,
                             std::vector<PoseSigma> sigmas)
    : source_(std::move(source)),
      time_(time_unix_ms),
      settings_(std::move(settings)),
      sigmas_(std::move(sigmas)) {
  settings_.absence.Check();
  settings_.evidence.Check();
}

void AbsenceLedger::Load(const storage::TreeRecord& tree) { stored_.emplace(*tree.id, tree); }

algorithms::TreeEvidence& AbsenceLedger::EvidenceOf(int64_t id) {
  auto it = evidence_.find(id);
  if (it != evidence_.end()) return it->second;
  const auto stored = stored_.find(id);
  return evidence_[id] =
             stored == stored_.end() ? algorithms::TreeEvidence{} : ToTreeEvidence(stored->second);
}

bool AbsenceLedger::Standing(int64_t id, const storage::TreeRecord* stored) const {
  const auto known = evidence_.find(id);
  if (known != evidence_.end()) return known->second.sightings > 0;
  return stored != nullptr && stored->last_seen_unix_ms.has_value();
}

AbsenceLedger::View AbsenceLedger::Classify(size_t index,
                                            const algorithms::FrameObservations& frame,
                                            std::vector<NearTree> nearby) {
  View view;
  std::stable_partition(nearby.begin(), nearby.end(),
                        [](const NearTree& near) { return !near.candidate; });
  view.trees = std::move(nearby);
  std::vector<algorithms::MapTree> established, candidates;
  std::vector<char> standing;
  for (const NearTree& near : view.trees) {
    (near.candidate ? candidates : established).push_back(near.tree);
    if (near.candidate) continue;
    const auto stored = stored_.find(near.tree.id);
    standing.push_back(Standing(near.tree.id, stored != stored_.end() ? &stored->second : nullptr));
  }
  algorithms::AbsenceObservation observation;
  observation.map_from_sensor = frame.map_from_sensor;
  if (index < sigmas_.size()) {
    observation.pose_sigma_xy = sigmas_[index].xy;
    observation.pose_sigma_yaw = sigmas_[index].yaw;
  }
  observation.trees = frame.trees;
  // What the frame teaches about the sensor, then the classification with the call's pooled
  // model (a frame over a clear-cut, which detects no map tree, uses what the others taught).
  view.result =
      algorithms::ExpectTrees(established, standing, candidates, observation, settings_.absence);
  pool_.Add(view.result);
  const algorithms::AbsenceOptions pooled = pool_.Apply(settings_.absence);
  current_.reset();
  if (pooled.range > 0 && pooled.detection_probability > 0) {
    view.result = algorithms::ExpectTrees(established, standing, candidates, observation, pooled);
    current_ = PastView{frame.frame_id, std::move(observation), pooled, std::move(established),
                        std::move(standing)};
  }
  return view;
}

void AbsenceLedger::LookBackAt(const PastView& view,
                               std::span<const algorithms::MapTree> view_established,
                               std::span<const char> view_standing,
                               std::span<const algorithms::TreeEstimate> started) {
  const Eigen::Vector2d sensor = view.observation.map_from_sensor.translation().head<2>();
  std::vector<algorithms::MapTree> reach;
  double farthest = 0;
  for (const algorithms::TreeEstimate& tree : started) {
    const double range = (tree.position.head<2>() - sensor).norm();
    if (gone_.count(tree.id) == 0 && range <= view.options.range) {
      reach.push_back({tree.id, tree.position, tree.dbh});
      farthest = std::max(farthest, range);
    }
  }
  if (reach.empty()) return;
  // Only what is nearer than the farthest of them (and its gate) can hide or see one of them;
  // the sensor model is known, so nothing else is needed.
  const double near = farthest + view.options.gate_distance;
  std::vector<algorithms::MapTree> established;
  std::vector<char> standing;
  for (size_t i = 0; i < view_established.size(); ++i) {
    if ((view_established[i].position.head<2>() - sensor).norm() <= near) {
      established.push_back(view_established[i]);
      standing.push_back(i < view_standing.size() && view_standing[i]);
    }
  }
  algorithms::AbsenceObservation observation = view.observation;
  std::erase_if(observation.trees, [&](const algorithms::DetectedTree& tree) {
    return ((observation.map_from_sensor * tree.position).head<2>() - sensor).norm() > near;
  });
  const algorithms::AbsenceResult result =
      algorithms::ExpectTrees(established, standing, reach, observation, view.options);
  for (size_t j = 0; j < reach.size(); ++j) {
    if (algorithms::AddView(EvidenceOf(reach[j].id), result.trees[established.size() + j],
                            /*candidate=*/true, source_, view.frame_id, time_,
                            settings_.evidence)) {
      gone_.insert(reach[j].id);
    }
  }
}

void AbsenceLedger::LookBack(std::span<const algorithms::TreeEstimate> started) {
  for (const PastView& view : views_) {
    LookBackAt(view, view.established, view.standing, started);
  }
}

void AbsenceLedger::LookBackStored(storage::MergeReader& reader,
                                   std::span<const algorithms::TreeEstimate> started) {
  const algorithms::AbsenceOptions options = pool_.Apply(settings_.absence);
  if (started.empty() || !(options.range > 0 && options.detection_probability > 0)) return;
  Eigen::Vector2d lo = started.front().position.head<2>(), hi = lo;
  for (const algorithms::TreeEstimate& tree : started) {
    lo = lo.cwiseMin(tree.position.head<2>());
    hi = hi.cwiseMax(tree.position.head<2>());
  }
  // The source's earlier frames around the started trees: their detections there, by frame.
  std::map<std::tuple<int64_t, double, double>, PastView> views;  // by frame and sensor
  for (const storage::ObservationRecord& row : reader.ObservationsOfSourceIn(
           source_, storage::CellOf(lo.x() - options.range, lo.y() - options.range),
           storage::CellOf(hi.x() + options.range, hi.y() + options.range))) {
    if (row.prior || row.summary) continue;
    PastView& view = views[{row.frame_id, row.sensor_x, row.sensor_y}];
    const Eigen::Vector3d sensor(row.sensor_x, row.sensor_y, row.sensor_z);
    view.frame_id = row.frame_id;
    view.observation.map_from_sensor = algorithms::Pose3::Identity();
    view.observation.map_from_sensor.translation() = sensor;
    algorithms::DetectedTree seen;
    seen.position = Eigen::Vector3d(row.x, row.y, row.z.value_or(row.sensor_z)) - sensor;
    seen.dbh = row.dbh.value_or(algorithms::kUnknown);
    view.observation.trees.push_back(seen);
  }
  // The confirmed trees around them, read once for every view.
  const double reach = options.range + options.gate_distance;
  std::vector<algorithms::MapTree> established;
  std::vector<char> standing;
  for (const storage::TreeRecord& tree : reader.TreesInBox(
           {lo.x() - 2 * reach, lo.y() - 2 * reach, hi.x() + 2 * reach, hi.y() + 2 * reach})) {
    if (tree.status != storage::TreeStatus::kConfirmed || gone_.count(*tree.id) != 0) continue;
    established.push_back(ToMapTree(tree));
    standing.push_back(Standing(*tree.id, &tree));
  }
  for (auto& [frame, view] : views) {
    view.options = options;
    LookBackAt(view, established, standing, started);
  }
}

int AbsenceLedger::Apply(const View& view, int64_t frame_id,
                         std::span<const algorithms::TreeEstimate> started) {
  int missed = 0;
  for (size_t i = 0; i < view.trees.size(); ++i) {
    const algorithms::TreeVisibility& visibility = view.result.trees[i];
    if (gone_.count(visibility.id) != 0) continue;
    missed += visibility.visibility == algorithms::Visibility::kMissed;
    if (algorithms::AddView(EvidenceOf(visibility.id), visibility, view.trees[i].candidate, source_,
                            frame_id, time_, settings_.evidence)) {
      gone_.insert(visibility.id);
    }
  }
  for (const algorithms::TreeEstimate& tree : started) {
    algorithms::AddSighting(EvidenceOf(tree.id), source_, time_);
  }
  LookBack(started);
  if (current_) views_.push_back(std::move(*current_));
  current_.reset();
  return missed;
}

void AbsenceLedger::Finish(storage::MergeReader& reader, storage::MapChanges& changes) const {
  std::erase_if(changes.put_trees,
                [&](const storage::TreeRecord& tree) { return gone_.count(*tree.id) != 0; });
  std::set<int64_t> put;
  for (storage::TreeRecord& tree : changes.put_trees) {
    put.insert(*tree.id);
    const auto weighed = evidence_.find(*tree.id);
    if (weighed != evidence_.end()) {
      SetEvidence(tree, weighed->second);
    } else if (stored_.count(*tree.id) == 0 && !tree.last_seen_unix_ms) {
      algorithms::TreeEvidence seen;
      algorithms::AddSighting(seen, source_, time_);
      SetEvidence(tree, seen);
    }
  }
  // Trees the merge removed (merged into another, left without rows) keep no evidence.
  const std::set<int64_t> merged_away(changes.removed_trees.begin(), changes.removed_trees.end());
  for (const auto& [id, evidence] : evidence_) {
    const auto stored = stored_.find(id);
    if (gone_.count(id) != 0 || put.count(id) != 0 || merged_away.count(id) != 0 ||
        stored == stored_.end()) {
      continue;
    }
    storage::TreeRecord tree = stored->second;
    SetEvidence(tree, evidence);
    if (tree != stored->second) changes.put_trees.push_back(std::move(tree));
  }
  std::vector<int64_t> removed;
  for (const int64_t id : gone_) {
    const auto stored = stored_.find(id);
    if (stored == stored_.end()) continue;  // a candidate of this call: never stored
    removed.push_back(id);
    if (std::find(changes.removed_trees.begin(), changes.removed_trees.end(), id) ==
        changes.removed_trees.end()) {
      changes.removed_trees.push_back(id);
    }
    const algorithms::TreeEvidence& evidence = evidence_.at(id);
    const bool candidate = stored->second.status == storage::TreeStatus::kCandidate;
    json note = {
        {"kind", candidate ? "retired" : "removed"},
        {"x", stored->second.x},
        {"y", stored->second.y},
        {"log_likelihood_ratio", algorithms::GoneLogLikelihoodRatio(evidence, settings_.evidence)},
        {"threshold", settings_.evidence.Threshold(candidate)},
        {"misses", evidence.misses},
        {"groups", GroupsJson(evidence)}};
    if (stored->second.dbh) note["dbh"] = *stored->second.dbh;
    if (stored->second.last_seen_unix_ms) {
      note["last_seen_unix_ms"] = *stored->second.last_seen_unix_ms;
    }
    changes.removals.push_back({id, note.dump()});
  }
  if (removed.empty()) return;
  for (const storage::ObservationRecord& row : reader.ObservationsOfTrees(removed)) {
    (row.summary ? changes.removed_summaries : changes.removed_observations).push_back(row.id);
  }
  for (const storage::ObservationRecord& row : reader.FoldedObservationsOfTrees(removed)) {
    changes.removed_observations.push_back(row.id);
  }
}

}  // namespace forestmap::server
