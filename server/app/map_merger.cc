#include "server/app/map_merger.h"

#include <map>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "server/app/errors.h"
#include "server/app/merge_region.h"
#include "server/app/tree_records.h"

namespace forestmap::server {
namespace {

// The trees a frame is merged with incrementally (for its counts) reach this far beyond the
// merge's own reach (m), so that a tree moving a little between frames of one request is found.
constexpr double kBoxMargin = 1.0;

struct WorkingTree {
  algorithms::TreeEstimate estimate;
  std::map<std::string, std::string> attributes;  // survey columns, kept
  std::set<std::string> null_attributes;          // survey columns unknown for this tree, kept
  std::optional<int64_t> last_seen_unix_ms;       // evidence of absence, kept
  std::optional<std::string> evidence;
  bool changed = false;
  bool is_new = false;  // created by this merge (not in the store yet)
  // A surveyed tree without observation rows: its prior becomes a row when it changes.
  std::optional<algorithms::TreeObservation> unsaved_prior;
};

storage::Extent FrameBox(const algorithms::FrameObservations& frame,
                         const algorithms::MergeOptions& options) {
  const Eigen::Vector3d sensor = frame.map_from_sensor.translation();
  const double reach = options.max_range + options.gate_distance + kBoxMargin;
  return {sensor.x() - reach, sensor.y() - reach, sensor.x() + reach, sensor.y() + reach};
}

bool Inside(const storage::Extent& box, const Eigen::Vector3d& p) {
  return p.x() >= box.min_x && p.x() <= box.max_x && p.y() >= box.min_y && p.y() <= box.max_y;
}

// The tree's estimate as a stored row, with what it keeps of its stored row.
storage::TreeRecord RecordOf(const WorkingTree& tree, const algorithms::TreeEstimate& estimate) {
  storage::TreeRecord record = ToTreeRecord(estimate, tree.attributes, tree.null_attributes);
  record.last_seen_unix_ms = tree.last_seen_unix_ms;
  record.evidence = tree.evidence;
  return record;
}

// Observation rows grouped by tree id.
std::map<int64_t, std::vector<algorithms::TreeObservation>> ByTree(
    const std::vector<storage::ObservationRecord>& rows) {
  std::map<int64_t, std::vector<algorithms::TreeObservation>> grouped;
  for (const storage::ObservationRecord& row : rows) {
    grouped[row.tree_id].push_back(ToTreeObservation(row));
  }
  return grouped;
}

struct Loaded {
  std::map<int64_t, WorkingTree> working;
  std::vector<storage::ObservationRecord> rows;  // current rows of the region (not dropped)
  std::map<int64_t, std::vector<storage::ObservationRecord>> foldable_outside;  // MergeRegion's
};

// The trees of the region that `seeds` join (LoadMergeRegion), with their estimates rebuilt from
// their rows; rows whose id is in `dropped` are left out (a source being removed). Every stored
// tree of the region is loaded into `ledger` when there is one.
Loaded LoadTrees(storage::MergeReader& reader,
                 const std::vector<algorithms::TreeObservation>& seeds,
                 const algorithms::MergeOptions& options, const std::set<int64_t>& dropped = {},
                 AbsenceLedger* ledger = nullptr) {
  MergeRegion region = LoadMergeRegion(reader, seeds, options);
  Loaded loaded;
  loaded.foldable_outside = std::move(region.foldable_outside);
  for (storage::ObservationRecord& row : region.rows) {
    if (dropped.count(row.id) == 0) loaded.rows.push_back(std::move(row));
  }
  const auto observations = ByTree(loaded.rows);
  std::map<int64_t, algorithms::TreeObservation> priors;
  for (algorithms::TreeObservation& prior : region.unsaved_priors) {
    priors.emplace(prior.tree_id, std::move(prior));
  }
  for (auto& [id, record] : region.trees) {
    if (ledger) ledger->Load(record);
    WorkingTree tree;
    tree.last_seen_unix_ms = record.last_seen_unix_ms;
    tree.evidence = std::move(record.evidence);
    tree.attributes = std::move(record.attributes);
    tree.null_attributes = std::move(record.null_attributes);
    const auto rows = observations.find(id);
    const auto prior_of = priors.find(id);
    if (rows != observations.end()) {
      tree.estimate = algorithms::EstimateFromObservations(id, rows->second, options);
    } else if (prior_of == priors.end()) {
      tree.estimate.id = id;  // every row dropped: the rebuild removes the tree
    } else {
      const algorithms::TreeObservation& prior = prior_of->second;
      tree.estimate = algorithms::EstimateFromObservations(id, {&prior, 1}, options);
      tree.unsaved_prior = prior;
    }
    loaded.working.emplace(id, std::move(tree));
  }
  return loaded;
}

// Identifies an observation row across ConsolidateTrees, which reorders rows and may change
// their tree: where it was seen and what was seen.
using RowKey = std::tuple<std::string, int64_t, int32_t, double, double>;
RowKey KeyOf(const std::string& source, int64_t frame, int32_t detection, double x, double y) {
  return {source, frame, detection, x, y};
}

// What folding may fold of one tree: its rows that were stored and keep it.
struct Foldable {
  std::optional<int64_t> summary_id;                     // its stored summary row
  const algorithms::TreeObservation* summary = nullptr;  // that summary, or a new one
  std::vector<std::pair<int64_t, const algorithms::TreeObservation*>> rows;  // (row id, row)
};

// Folds every tree of `foldable` that keeps at least options.fold_rows stored rows (not counting
// its summary): its summary and those rows become one new summary row, and the rows are stored
// again as folded (storage::MapChanges::folded_observations). A new summary of a tree that does
// not fold (a source removal's) is added as it is.
void Fold(const std::map<int64_t, Foldable>& foldable,
          const std::map<int64_t, const storage::ObservationRecord*>& stored_rows,
          const algorithms::MergeOptions& options, storage::MapChanges& changes) {
  for (const auto& [tree, fold] : foldable) {
    if (static_cast<int>(fold.rows.size()) < options.fold_rows) {
      if (fold.summary && !fold.summary_id) {
        changes.added_observations.push_back(ToObservationRecord(*fold.summary));
      }
      continue;
    }
    std::vector<algorithms::TreeObservation> rows;
    if (fold.summary) rows.push_back(*fold.summary);
    for (const auto& [id, row] : fold.rows) {
      rows.push_back(*row);
      changes.folded_observations.push_back(*stored_rows.at(id));
    }
    if (fold.summary_id) changes.removed_summaries.push_back(*fold.summary_id);
    changes.added_observations.push_back(
        ToObservationRecord(algorithms::SummaryObservation(tree, rows, options)));
  }
}

// Rebuilds the region (its stored rows, the new rows and unsaved survey priors: whole connected
// components of the map's rows) afresh with algorithms::RebuildTrees, then turns the outcome into
// changes: moved rows are closed and re-inserted under their new tree, trees that gained, lost
// or changed rows (or are in `lost`: their dropped rows are closed by the caller) are put, trees
// left empty are removed, and trees with many stored rows fold them (Fold). Until a tree folds,
// the region's trees are what one rebuild of all the map's rows gives them, whatever the order
// in which requests arrived; a summary row fixes the association of the rows it folded.
storage::MapChanges Consolidate(Loaded& loaded,
                                const std::vector<algorithms::TreeObservation>& fresh,
                                const std::set<int64_t>& lost, int64_t next_free_id,
                                const algorithms::MergeOptions& options) {
  std::vector<algorithms::TreeEstimate> trees;
  for (const auto& [id, tree] : loaded.working) trees.push_back(tree.estimate);
  std::vector<algorithms::TreeObservation> rows;
  std::map<RowKey, std::vector<std::pair<int64_t, int64_t>>> stored;  // key -> (row id, tree)
  std::map<int64_t, const storage::ObservationRecord*> stored_rows;   // by row id
  for (const storage::ObservationRecord& row : loaded.rows) {
    stored_rows.emplace(row.id, &row);
    rows.push_back(ToTreeObservation(row));
    stored[KeyOf(row.source, row.frame_id, row.detection_index, row.x, row.y)].emplace_back(
        row.id, row.tree_id);
  }
  for (const auto& [id, tree] : loaded.working) {
    if (tree.unsaved_prior) rows.push_back(*tree.unsaved_prior);
  }
  rows.insert(rows.end(), fresh.begin(), fresh.end());
  const algorithms::ConsolidateResult result =
      algorithms::RebuildTrees(trees, rows, next_free_id, options);

  storage::MapChanges changes;
  std::set<int64_t> changed = lost;
  std::vector<const algorithms::TreeObservation*> priors;
  std::map<int64_t, Foldable> foldable;
  for (const algorithms::TreeObservation& row : result.observations) {
    auto it = stored.find(
        KeyOf(row.source, row.frame_id, row.detection_index, row.position.x(), row.position.y()));
    if (it != stored.end() && !it->second.empty()) {
      const auto [row_id, old_tree] = it->second.back();
      it->second.pop_back();
      if (old_tree == row.tree_id) {
        Foldable& fold = foldable[row.tree_id];
        if (row.summary) {
          fold.summary_id = row_id, fold.summary = &row;
        } else {
          fold.rows.emplace_back(row_id, &row);
        }
        continue;
      }
      // A summary keeps its tree (RebuildTrees): its folded rows refer to it.
      if (row.summary) throw std::logic_error("merge: a summary row changed its tree");
      changes.removed_observations.push_back(row_id);
      changed.insert(old_tree);
    } else if (row.prior) {
      priors.push_back(&row);  // saved only with its tree, below
      continue;
    } else if (row.summary) {
      foldable[row.tree_id].summary = &row;  // a new summary: added by Fold
      changed.insert(row.tree_id);
      continue;
    }
    changes.added_observations.push_back(ToObservationRecord(row));
    changed.insert(row.tree_id);
  }
  std::set<int64_t> removed(result.removed_ids.begin(), result.removed_ids.end());
  for (const algorithms::TreeObservation* prior : priors) {
    if (changed.count(prior->tree_id) != 0) {
      changes.added_observations.push_back(ToObservationRecord(*prior));
    }
  }
  // Neighbours outside the region keep their rows and trees: folding them changes no tree.
  std::vector<algorithms::TreeObservation> outside_rows;
  for (const auto& [tree, records] : loaded.foldable_outside) {
    for (const storage::ObservationRecord& record : records) {
      outside_rows.push_back(ToTreeObservation(record));
    }
  }
  const algorithms::TreeObservation* outside_row = outside_rows.data();
  for (const auto& [tree, records] : loaded.foldable_outside) {
    Foldable& fold = foldable[tree];
    for (const storage::ObservationRecord& record : records) {
      stored_rows.emplace(record.id, &record);
      if (outside_row->summary) {
        fold.summary_id = record.id, fold.summary = outside_row;
      } else {
        fold.rows.emplace_back(record.id, outside_row);
      }
      ++outside_row;
    }
  }
  Fold(foldable, stored_rows, options, changes);
  for (const algorithms::TreeEstimate& tree : result.trees) {
    if (changed.count(tree.id) == 0) continue;
    const auto it = loaded.working.find(tree.id);
    changes.put_trees.push_back(it != loaded.working.end() ? RecordOf(it->second, tree)
                                                           : ToTreeRecord(tree, {}));
  }
  for (const int64_t id : removed) {
    const auto it = loaded.working.find(id);
    if (it != loaded.working.end() && !it->second.is_new) changes.removed_trees.push_back(id);
  }
  return changes;
}

// The rows of `frames` each on its own, before any merging: what the merge region grows from.
std::vector<algorithms::TreeObservation> SeedsOf(
    const std::vector<algorithms::FrameObservations>& frames,
    const algorithms::MergeOptions& options) {
  std::vector<algorithms::TreeObservation> seeds;
  for (const algorithms::FrameObservations& frame : frames) {
    const std::vector<algorithms::TreeObservation> rows = algorithms::ObserveFrame(frame, options);
    seeds.insert(seeds.end(), rows.begin(), rows.end());
  }
  return seeds;
}

FrameMergeCounts CountsOf(const algorithms::MergeResult& result) {
  FrameMergeCounts counts;
  counts.associated = result.associated;
  counts.added = result.created;
  counts.promoted = static_cast<int>(result.promoted_ids.size());
  counts.ignored = result.skipped;
  return counts;
}

// Moves the updated and new trees of one frame's merge (ids resolved) into `working`.
void Apply(algorithms::MergeResult& result, std::map<int64_t, WorkingTree>& working) {
  for (algorithms::TreeEstimate& tree : result.updated_trees) {
    WorkingTree& target = working.at(tree.id);
    target.estimate = std::move(tree);
    target.changed = true;
  }
  for (algorithms::TreeEstimate& tree : result.new_trees) {
    WorkingTree created;
    created.estimate = std::move(tree);
    created.changed = true;
    created.is_new = true;
    working.emplace(created.estimate.id, std::move(created));
  }
}

// The changes of an incremental merge: every changed tree (with its unsaved survey prior, now
// a row) and the new observation rows.
storage::MapChanges ChangesOfWorkingTrees(const std::map<int64_t, WorkingTree>& working,
                                          const std::vector<algorithms::TreeObservation>& rows) {
  storage::MapChanges changes;
  for (const auto& [id, tree] : working) {
    if (!tree.changed) continue;
    changes.put_trees.push_back(RecordOf(tree, tree.estimate));
    if (tree.unsaved_prior) {
      changes.added_observations.push_back(ToObservationRecord(*tree.unsaved_prior));
    }
  }
  for (const algorithms::TreeObservation& row : rows) {
    changes.added_observations.push_back(ToObservationRecord(row));
  }
  return changes;
}

// The live trees near a frame's sensor (in `box`) for its evidence of absence: those of the
// merge (`working`) as they stand, and the stored ones around them, loaded into the ledger.
std::vector<NearTree> NearTrees(storage::MergeReader& reader, AbsenceLedger& ledger,
                                const storage::Extent& box,
                                const std::map<int64_t, WorkingTree>& working) {
  std::vector<NearTree> near;
  for (const auto& [id, tree] : working) {
    if (ledger.IsGone(id) || !Inside(box, tree.estimate.position)) continue;
    near.push_back({{id, tree.estimate.position, tree.estimate.dbh},
                    tree.estimate.status == algorithms::TreeStatus::kCandidate});
  }
  for (const storage::TreeRecord& record : reader.TreesInBox(box)) {
    if (working.count(*record.id) != 0 || ledger.IsGone(*record.id)) continue;
    ledger.Load(record);
    near.push_back({ToMapTree(record), record.status == storage::TreeStatus::kCandidate});
  }
  return near;
}

// Takes the trees the evidence showed gone, and their rows, out of the merge (the ledger removes
// the stored ones: AbsenceLedger::Finish).
void DropGone(Loaded& loaded, std::vector<algorithms::TreeObservation>& fresh,
              const std::set<int64_t>& gone) {
  for (const int64_t id : gone) {
    loaded.working.erase(id);
    loaded.foldable_outside.erase(id);
  }
  std::erase_if(loaded.rows, [&](const storage::ObservationRecord& row) {
    return gone.count(row.tree_id) != 0;
  });
  std::erase_if(
      fresh, [&](const algorithms::TreeObservation& row) { return gone.count(row.tree_id) != 0; });
}

}  // namespace

FramesMerge MergeFrames(storage::MergeReader& reader,
                        const std::vector<algorithms::FrameObservations>& frames,
                        const algorithms::MergeOptions& options, bool consolidate,
                        AbsenceLedger* ledger) {
  Loaded loaded = LoadTrees(reader, SeedsOf(frames, options), options, {}, ledger);
  std::map<int64_t, WorkingTree>& working = loaded.working;
  int64_t next_id = reader.NextFreeTreeId();
  FramesMerge merge;
  std::vector<algorithms::TreeObservation> rows;
  std::vector<algorithms::TreeEstimate> nearby;
  for (size_t f = 0; f < frames.size(); ++f) {
    const algorithms::FrameObservations& frame = frames[f];
    const storage::Extent box = FrameBox(frame, options);
    AbsenceLedger::View view;
    if (ledger) view = ledger->Classify(f, frame, NearTrees(reader, *ledger, box, working));
    nearby.clear();
    for (const auto& [id, tree] : working) {
      if (!(ledger && ledger->IsGone(id)) && Inside(box, tree.estimate.position)) {
        nearby.push_back(tree.estimate);
      }
    }
    algorithms::MergeResult result = algorithms::MergeFrame(nearby, frame, options);
    std::vector<int64_t> new_ids;
    for (size_t k = 0; k < result.new_trees.size(); ++k) new_ids.push_back(next_id++);
    algorithms::ResolveNewIds(result, new_ids);
    Apply(result, working);
    rows.insert(rows.end(), result.observations.begin(), result.observations.end());
    merge.counts.push_back(CountsOf(result));
    if (ledger) {
      const size_t gone_before = ledger->gone().size();
      merge.counts.back().missed = ledger->Apply(view, frame.frame_id, result.new_trees);
      merge.counts.back().removed = static_cast<int>(ledger->gone().size() - gone_before);
    }
  }
  if (ledger) {
    std::vector<algorithms::TreeEstimate> started;
    for (const auto& [id, tree] : working) {
      if (tree.is_new && !ledger->IsGone(id)) started.push_back(tree.estimate);
    }
    ledger->LookBackStored(reader, started);
    DropGone(loaded, rows, ledger->gone());
  }
  merge.changes = consolidate ? Consolidate(loaded, rows, {}, next_id, options)
                              : ChangesOfWorkingTrees(working, rows);
  if (ledger) ledger->Finish(reader, merge.changes);
  return merge;
}

SourceRemoval RemoveSourceChanges(storage::MergeReader& reader, const std::string& source,
                                  const algorithms::MergeOptions& options) {
  const std::vector<storage::ObservationRecord> removed = reader.ObservationsOfSource(source);
  if (removed.empty()) {
    throw ServiceError(
        ErrorCode::kNotFound,
        "map \"" + reader.map().name + "\" has no observations of source \"" + source + "\"");
  }
  std::set<int64_t> removed_ids;
  std::set<int64_t> lost;
  std::vector<int64_t> folded_trees;
  std::vector<algorithms::TreeObservation> seeds;
  for (const storage::ObservationRecord& row : removed) {
    removed_ids.insert(row.id);
    lost.insert(row.tree_id);
    if (row.folded) folded_trees.push_back(row.tree_id);
    seeds.push_back(ToTreeObservation(row));
  }
  // Trees that lose folded rows: their summaries are made again from the folded rows that stay.
  std::set<int64_t> dropped = removed_ids;
  std::vector<int64_t> summaries;
  std::vector<algorithms::TreeObservation> fresh;
  if (!folded_trees.empty()) {
    for (const storage::ObservationRecord& row : reader.ObservationsOfTrees(folded_trees)) {
      if (!row.summary) continue;
      summaries.push_back(row.id);
      dropped.insert(row.id);
      seeds.push_back(ToTreeObservation(row));
    }
    std::map<int64_t, std::vector<algorithms::TreeObservation>> kept;
    for (const storage::ObservationRecord& row : reader.FoldedObservationsOfTrees(folded_trees)) {
      if (removed_ids.count(row.id) == 0) kept[row.tree_id].push_back(ToTreeObservation(row));
    }
    for (const auto& [tree, rows] : kept) {
      fresh.push_back(algorithms::SummaryObservation(tree, rows, options));
    }
  }
  // The components the source's rows were in, rebuilt from the rows that remain.
  Loaded loaded = LoadTrees(reader, seeds, options, dropped);
  SourceRemoval removal;
  removal.changes = Consolidate(loaded, fresh, lost, reader.NextFreeTreeId(), options);
  removal.changes.removed_observations.insert(removal.changes.removed_observations.end(),
                                              removed_ids.begin(), removed_ids.end());
  removal.changes.removed_summaries.insert(removal.changes.removed_summaries.end(),
                                           summaries.begin(), summaries.end());
  removal.trees_updated = static_cast<int64_t>(removal.changes.put_trees.size());
  removal.trees_removed = static_cast<int64_t>(removal.changes.removed_trees.size());
  return removal;
}

}  // namespace forestmap::server
