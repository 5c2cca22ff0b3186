#include "algorithms/merging/map_merge.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <tuple>

#include "algorithms/merging/map_merge_internal.h"

namespace forestmap::algorithms {

const char* ToString(TreeStatus status) {
  return status == TreeStatus::kConfirmed ? "confirmed" : "candidate";
}

void WeightedMoments1::Add(double value, double w) {
  if (!(w > 0)) return;
  WeightedMoments1 one;
  one.weight = w;
  one.mean = value;
  one.count = 1;
  Merge(one);
}

// Chan, Golub & LeVeque (1979) pairwise combination of weighted moments.
void WeightedMoments1::Merge(const WeightedMoments1& other) {
  if (other.weight <= 0) return;
  const double total = weight + other.weight;
  const double delta = other.mean - mean;
  mean += delta * other.weight / total;
  m2 += other.m2 + delta * delta * weight * other.weight / total;
  weight = total;
  count += other.count;
}

void WeightedMoments2::Add(const Eigen::Vector2d& value, double w) {
  if (!(w > 0)) return;
  WeightedMoments2 one;
  one.weight = w;
  one.mean = value;
  one.count = 1;
  Merge(one);
}

void WeightedMoments2::Merge(const WeightedMoments2& other) {
  if (other.weight <= 0) return;
  const double total = weight + other.weight;
  const Eigen::Vector2d delta = other.mean - mean;
  mean += delta * (other.weight / total);
  m2 += other.m2 + delta.squaredNorm() * weight * other.weight / total;
  weight = total;
  count += other.count;
}

void MergeOptions::Check() const {
  auto require = [](bool ok, const char* field) {
    if (!ok) throw std::invalid_argument(std::string("MergeOptions.") + field + " is invalid");
  };
  require(sigma_xy_base > 0, "sigma_xy_base (must be > 0 m)");
  require(sigma_xy_per_m >= 0, "sigma_xy_per_m (must be >= 0)");
  require(score_floor > 0 && score_floor <= 1, "score_floor (must be in (0, 1])");
  require(sigma_dbh_base > 0, "sigma_dbh_base (must be > 0 m)");
  require(sigma_dbh_per_m >= 0, "sigma_dbh_per_m (must be >= 0)");
  require(max_range > 0, "max_range (must be > 0 m)");
  require(min_dbh >= 0, "min_dbh (must be >= 0 m)");
  require(gate_distance > 0, "gate_distance (must be > 0 m)");
  require(gate_sigmas > 0, "gate_sigmas (must be > 0)");
  require(pose_sigma >= 0, "pose_sigma (must be >= 0 m)");
  require(dbh_gate_abs >= 0, "dbh_gate_abs (must be >= 0 m)");
  require(dbh_gate_rel >= 0, "dbh_gate_rel (must be >= 0)");
  require(dbh_cost >= 0, "dbh_cost (must be >= 0)");
  require(dbh_outlier_distance >= 0, "dbh_outlier_distance (must be >= 0 m)");
  require(promotion_views >= 1 && promotion_views <= TreeEstimate::kMaxViewAnchors,
          "promotion_views (must be in [1, 8])");
  require(min_view_separation >= 0, "min_view_separation (must be >= 0 m)");
  require(survey_sigma_xy > 0, "survey_sigma_xy (must be > 0 m)");
  require(survey_sigma_dbh > 0, "survey_sigma_dbh (must be > 0 m)");
  require(duplicate_distance >= 0, "duplicate_distance (must be >= 0 m)");
  require(max_shared_frames >= 0 && max_shared_frames <= 1, "max_shared_frames (in [0, 1])");
  require(min_shared_frames >= 1, "min_shared_frames (must be >= 1)");
  require(consolidate_iterations >= 0, "consolidate_iterations (must be >= 0)");
  require(fold_rows >= 2, "fold_rows (must be >= 2)");
}

namespace internal {

bool CanonicalLess(const TreeObservation& a, const TreeObservation& b) {
  return std::tie(a.frame_id, a.source, a.detection_index, a.tree_id) <
         std::tie(b.frame_id, b.source, b.detection_index, b.tree_id);
}

void Finalize(TreeEstimate& tree, const MergeOptions& options) {
  tree.position.x() = tree.xy.mean.x();
  tree.position.y() = tree.xy.mean.y();
  tree.position.z() = tree.z.count > 0 ? tree.z.mean : kUnknown;
  // Sigma of the mean: the model's 1/sqrt(sum w), or the observed scatter when larger
  // (per axis: m2 / weight / 2 is the weighted per-axis variance of one observation).
  if (tree.xy.weight > 0) {
    double var = 1.0 / tree.xy.weight;
    if (tree.xy.count >= 2) {
      var = std::max(var, tree.xy.m2 / tree.xy.weight / 2.0 / tree.xy.count);
    }
    tree.position_sigma = std::sqrt(var);
  } else {
    tree.position_sigma = kUnknown;
  }
  if (tree.dbh_stats.weight > 0) {
    tree.dbh = tree.dbh_stats.mean;
    double var = 1.0 / tree.dbh_stats.weight;
    if (tree.dbh_stats.count >= 2) {
      var = std::max(var, tree.dbh_stats.m2 / tree.dbh_stats.weight / tree.dbh_stats.count);
    }
    tree.dbh_sigma = std::sqrt(var);
  } else {
    tree.dbh = kUnknown;
    tree.dbh_sigma = kUnknown;
  }
  tree.distinct_views = static_cast<int>(tree.view_anchors.size());
  tree.status = (tree.surveyed || tree.distinct_views >= options.promotion_views)
                    ? TreeStatus::kConfirmed
                    : TreeStatus::kCandidate;
}

double ObservationSigma(const TreeObservation& observation) {
  return observation.weight_xy > 0 ? 1.0 / std::sqrt(observation.weight_xy) : 1e3;
}

PairCost AssociationCost(const TreeEstimate& tree, const TreeObservation& observation,
                         const MergeOptions& options) {
  PairCost out;
  const double d2 = (tree.position.head<2>() - observation.position.head<2>()).squaredNorm();
  if (d2 > options.gate_distance * options.gate_distance) return out;
  const double tree_sigma = IsKnown(tree.position_sigma) ? tree.position_sigma : 0.0;
  const double obs_sigma = ObservationSigma(observation);
  const double var =
      tree_sigma * tree_sigma + obs_sigma * obs_sigma + options.pose_sigma * options.pose_sigma;
  const double mahalanobis2 = d2 / var;
  if (mahalanobis2 > options.gate_sigmas * options.gate_sigmas) return out;
  out.cost = mahalanobis2;
  out.distance = std::sqrt(d2);
  if (IsKnown(tree.dbh) && IsKnown(observation.dbh) && observation.weight_dbh > 0) {
    const double diff = std::abs(tree.dbh - observation.dbh);
    const double gate =
        std::max(options.dbh_gate_abs, options.dbh_gate_rel * std::max(tree.dbh, observation.dbh));
    out.dbh_ok = diff <= gate;
    out.cost += options.dbh_cost * std::min(1.0, (diff / gate) * (diff / gate));
  }
  return out;
}

std::unique_ptr<KdTree<double, 2>> BuildTreeIndex(std::span<const TreeEstimate> trees) {
  std::vector<KdTree<double, 2>::Point> points;
  points.reserve(trees.size());
  for (const TreeEstimate& t : trees) points.push_back({t.position.x(), t.position.y()});
  return std::make_unique<KdTree<double, 2>>(std::move(points));
}

Association AssociateGreedy(std::span<const TreeEstimate> trees,
                            std::span<const TreeObservation> observations,
                            const MergeOptions& options) {
  if (trees.empty() || observations.empty()) {
    return {std::vector<int>(observations.size(), -1)};
  }
  return AssociateGreedy(trees, *BuildTreeIndex(trees), observations, options);
}

// Greedy one-to-one matching, cheapest first. Per-frame sets are small (< 300 detections, a few
// candidate trees each), where greedy by Mahalanobis distance equals the optimal assignment but
// for rare conflicts. Ties are broken by tree id and observation index, never by input order.
Association AssociateGreedy(std::span<const TreeEstimate> trees, const KdTree<double, 2>& kd,
                            std::span<const TreeObservation> observations,
                            const MergeOptions& options) {
  Association out{std::vector<int>(observations.size(), -1)};
  if (trees.empty() || observations.empty()) return out;
  // (DBH disagrees, cost, tree id, observation index, tree index).
  std::vector<std::tuple<bool, double, int64_t, int, int>> pairs;
  std::vector<std::pair<uint32_t, double>> near;
  for (size_t o = 0; o < observations.size(); ++o) {
    const Eigen::Vector3d& p = observations[o].position;
    kd.Radius({p.x(), p.y()}, options.gate_distance, near);
    for (const auto& [t, d2] : near) {
      const PairCost pair = AssociationCost(trees[t], observations[o], options);
      if (pair.cost < 0) continue;
      // A DBH disagreement is tolerated only very close to the tree (dbh_outlier_distance):
      // single DBH fits are often far off (partial arcs), while a distinct stem would stand
      // apart. Two stems cannot overlap: closer than the sum of the radii it is the same stem.
      // The row's DBH is then averaged with its weight like any other (rows are never
      // rewritten, so that the map depends on the set of rows, not on their order; Wild_V01
      // survey merge: median DBH difference to map.csv 4.4 -> 2.6 mm).
      if (!pair.dbh_ok && pair.distance > std::max(options.dbh_outlier_distance,
                                                   0.5 * (trees[t].dbh + observations[o].dbh))) {
        continue;
      }
      pairs.emplace_back(!pair.dbh_ok, pair.cost, trees[t].id, static_cast<int>(o), t);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<char> tree_used(trees.size(), 0);
  for (const auto& [dbh_disagrees, cost, id, o, t] : pairs) {
    if (out.tree[o] >= 0 || tree_used[t]) continue;
    out.tree[o] = t;
    tree_used[t] = 1;
  }
  return out;
}

}  // namespace internal

std::vector<TreeObservation> ObserveFrame(const FrameObservations& frame,
                                          const MergeOptions& options) {
  options.Check();
  if (!frame.map_from_sensor.matrix().allFinite()) {
    throw std::invalid_argument("frame " + std::to_string(frame.frame_id) + " of '" + frame.source +
                                "': non-finite map_from_sensor");
  }
  std::vector<TreeObservation> rows;
  rows.reserve(frame.trees.size());
  const Eigen::Vector3d sensor = frame.map_from_sensor.translation();
  for (size_t i = 0; i < frame.trees.size(); ++i) {
    const DetectedTree& tree = frame.trees[i];
    if (!tree.position.head<2>().allFinite()) continue;
    Eigen::Vector3d p = tree.position;
    const bool z_known = std::isfinite(p.z());
    if (!z_known) p.z() = 0;
    Eigen::Vector3d in_map = frame.map_from_sensor * p;
    if (!z_known) in_map.z() = kUnknown;
    const double range = (in_map.head<2>() - sensor.head<2>()).norm();
    if (range > options.max_range) continue;
    const double score = std::isfinite(tree.score) ? std::clamp(tree.score, 0.0, 1.0) : 0.5;
    const double quality = options.score_floor + (1 - options.score_floor) * score;
    const double sigma_xy =
        std::hypot(options.sigma_xy_base, options.sigma_xy_per_m * range) / quality;
    TreeObservation row;
    row.source = frame.source;
    row.frame_id = frame.frame_id;
    row.detection_index = static_cast<int>(i);
    row.position = in_map;
    row.weight_xy = 1.0 / (sigma_xy * sigma_xy);
    row.sensor_position = sensor;
    if (std::isfinite(tree.dbh) && tree.dbh > options.min_dbh) {
      // DBH errors did not grow with range on Wild_V01: sigma_dbh_per_m is 0 (a range term moved
      // the merged DBH away from the reference's plain mean: median |diff| 0.4 mm without, 10 mm
      // with 0.01 m/m).
      const double sigma_dbh =
          std::hypot(options.sigma_dbh_base, options.sigma_dbh_per_m * range) / quality;
      row.dbh = tree.dbh;
      row.weight_dbh = 1.0 / (sigma_dbh * sigma_dbh);
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

TreeObservation SurveyObservation(const MapTree& tree, const MergeOptions& options) {
  options.Check();
  TreeObservation row;
  row.tree_id = tree.id;
  row.source = "survey";
  row.frame_id = 0;
  row.detection_index = -1;
  row.position = tree.position;
  row.weight_xy = 1.0 / (options.survey_sigma_xy * options.survey_sigma_xy);
  // A survey has no sensor: the tree itself stands in, at height 0 when its height is unknown
  // (only the horizontal sensor position is ever used, and a stored row needs a finite one).
  row.sensor_position = tree.position;
  if (!std::isfinite(row.sensor_position.z())) row.sensor_position.z() = 0;
  if (IsKnown(tree.dbh) && tree.dbh > options.min_dbh) {
    row.dbh = tree.dbh;
    row.weight_dbh = 1.0 / (options.survey_sigma_dbh * options.survey_sigma_dbh);
  }
  row.prior = true;
  return row;
}

TreeObservation SummaryObservation(int64_t tree_id, std::span<const TreeObservation> rows,
                                   const MergeOptions& options) {
  if (rows.empty()) throw std::invalid_argument("SummaryObservation: no rows to fold");
  std::vector<TreeObservation> sorted(rows.begin(), rows.end());
  std::stable_sort(sorted.begin(), sorted.end(), internal::CanonicalLess);
  const TreeEstimate tree = EstimateFromObservations(tree_id, sorted, options);
  auto summary = std::make_shared<ObservationSummary>();
  summary->xy = tree.xy;
  summary->z = tree.z;
  summary->dbh = tree.dbh_stats;
  summary->rows = tree.observations;
  summary->surveyed = tree.surveyed;
  summary->view_anchors = tree.view_anchors;
  TreeObservation row;
  row.tree_id = tree_id;
  row.source = kSummarySource;
  row.frame_id = 0;
  row.detection_index = -2;
  row.position = Eigen::Vector3d(tree.xy.mean.x(), tree.xy.mean.y(),
                                 tree.z.count > 0 ? tree.z.mean : kUnknown);
  row.dbh = tree.dbh_stats.weight > 0 ? tree.dbh_stats.mean : kUnknown;
  row.weight_xy = tree.xy.weight;
  row.weight_dbh = tree.dbh_stats.weight;
  const Eigen::Vector2d sensor =
      tree.view_anchors.empty() ? tree.xy.mean : tree.view_anchors.front();
  row.sensor_position = Eigen::Vector3d(sensor.x(), sensor.y(), 0);
  row.summary = std::move(summary);
  return row;
}

namespace {

// The rows a summary stands for, added at once: moments merged, view anchors added in order.
void AddSummary(TreeEstimate& tree, const ObservationSummary& summary,
                const MergeOptions& options) {
  tree.xy.Merge(summary.xy);
  tree.z.Merge(summary.z);
  tree.dbh_stats.Merge(summary.dbh);
  tree.observations += summary.rows;
  tree.surveyed = tree.surveyed || summary.surveyed;
  tree.summarized = true;
  const double sep2 = options.min_view_separation * options.min_view_separation;
  for (const Eigen::Vector2d& view : summary.view_anchors) {
    if (static_cast<int>(tree.view_anchors.size()) >= TreeEstimate::kMaxViewAnchors) break;
    bool distinct = true;
    for (const Eigen::Vector2d& anchor : tree.view_anchors) {
      if ((anchor - view).squaredNorm() < sep2) distinct = false;
    }
    if (distinct) tree.view_anchors.push_back(view);
  }
  internal::Finalize(tree, options);
}

}  // namespace

void AddObservation(TreeEstimate& tree, const TreeObservation& observation,
                    const MergeOptions& options) {
  if (observation.summary) return AddSummary(tree, *observation.summary, options);
  tree.xy.Add(observation.position.head<2>(), observation.weight_xy);
  if (std::isfinite(observation.position.z())) {
    tree.z.Add(observation.position.z(), observation.weight_xy);
  }
  if (IsKnown(observation.dbh)) tree.dbh_stats.Add(observation.dbh, observation.weight_dbh);
  ++tree.observations;
  if (observation.prior) {
    tree.surveyed = true;
  } else if (static_cast<int>(tree.view_anchors.size()) < TreeEstimate::kMaxViewAnchors) {
    const Eigen::Vector2d view = observation.sensor_position.head<2>();
    const double sep2 = options.min_view_separation * options.min_view_separation;
    bool distinct = true;
    for (const Eigen::Vector2d& anchor : tree.view_anchors) {
      if ((anchor - view).squaredNorm() < sep2) distinct = false;
    }
    if (distinct) tree.view_anchors.push_back(view);
  }
  internal::Finalize(tree, options);
}

TreeEstimate EstimateFromObservations(int64_t id, std::span<const TreeObservation> observations,
                                      const MergeOptions& options) {
  options.Check();
  TreeEstimate tree;
  tree.id = id;
  for (const TreeObservation& row : observations) AddObservation(tree, row, options);
  internal::Finalize(tree, options);
  return tree;
}

MergeResult MergeFrame(std::span<const TreeEstimate> nearby_map_trees,
                       const FrameObservations& frame, const MergeOptions& options) {
  MergeResult result;
  result.assignment.assign(frame.trees.size(), 0);
  std::vector<TreeObservation> rows = ObserveFrame(frame, options);
  result.skipped = static_cast<int>(frame.trees.size() - rows.size());
  const internal::Association association =
      internal::AssociateGreedy(nearby_map_trees, rows, options);
  const std::vector<int>& assigned = association.tree;
  std::vector<int> updated_index(nearby_map_trees.size(), -1);
  for (size_t o = 0; o < rows.size(); ++o) {
    TreeObservation& row = rows[o];
    TreeEstimate* tree = nullptr;
    if (assigned[o] >= 0) {
      int& slot = updated_index[assigned[o]];
      if (slot < 0) {
        slot = static_cast<int>(result.updated_trees.size());
        result.updated_trees.push_back(nearby_map_trees[assigned[o]]);
      }
      tree = &result.updated_trees[slot];
      ++result.associated;
    } else {
      TreeEstimate fresh;
      fresh.id = -static_cast<int64_t>(result.new_trees.size()) - 1;
      result.new_trees.push_back(std::move(fresh));
      tree = &result.new_trees.back();
      ++result.created;
    }
    const TreeStatus before = tree->status;
    row.tree_id = tree->id;
    AddObservation(*tree, row, options);
    if (before == TreeStatus::kCandidate && tree->status == TreeStatus::kConfirmed) {
      result.promoted_ids.push_back(tree->id);
    }
    result.assignment[row.detection_index] = tree->id;
  }
  result.observations = std::move(rows);
  return result;
}

void ResolveNewIds(MergeResult& result, std::span<const int64_t> new_ids) {
  if (new_ids.size() != result.new_trees.size()) {
    throw std::invalid_argument("ResolveNewIds: " + std::to_string(new_ids.size()) + " ids for " +
                                std::to_string(result.new_trees.size()) + " new trees");
  }
  auto resolve = [&](int64_t& id) {
    if (id < 0) id = new_ids[static_cast<size_t>(-id - 1)];
  };
  for (int64_t& id : result.assignment) resolve(id);
  for (TreeEstimate& tree : result.new_trees) resolve(tree.id);
  for (TreeObservation& row : result.observations) resolve(row.tree_id);
  for (int64_t& id : result.promoted_ids) resolve(id);
}

}  // namespace forestmap::algorithms
