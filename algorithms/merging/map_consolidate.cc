// ConsolidateTrees and RebuildTrees (map_merge.h): order-free re-association and duplicate merging.
//
// Incremental merging is greedy: the first frame to see a tree decides where its candidate
// starts, and two uploads that see a new tree at the same time create two candidates.
// RebuildTrees makes the map depend on the set of observations only: the rows are split into
// connected components, and each component is merged afresh in canonical row order, then its
// duplicate trees are merged and every frame's rows re-associated one-to-one with the current
// estimates (a few k-means style sweeps, as ConsolidateTrees does for the current association).

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "algorithms/merging/map_merge.h"
#include "algorithms/merging/map_merge_internal.h"
#include "algorithms/merging/observation_components.h"

namespace forestmap::algorithms {
namespace {

using internal::CanonicalLess;

bool SameFrame(const TreeObservation& a, const TreeObservation& b) {
  return a.frame_id == b.frame_id && a.source == b.source;
}

[[noreturn]] void ThrowUnknownTree(const TreeObservation& row) {
  throw std::invalid_argument(
      "ConsolidateTrees: observation of frame " + std::to_string(row.frame_id) + " of '" +
      row.source + "' refers to tree " + std::to_string(row.tree_id) + ", which is not given");
}

// Tree ids handed out by one RebuildTrees call (shared by its components).
struct IdPool {
  int64_t next_free_id = 1;
  std::unordered_set<int64_t> taken, reserved;  // reserved: summarized trees', for them only
  bool Free(int64_t id) const { return taken.count(id) == 0 && reserved.count(id) == 0; }
};

// The trees a Restart grows, with a grid of 1 m cells (keyed by the floor of x and y, as int64_t:
// a negative double cast to unsigned is undefined) of their positions, to find the trees nearby.
struct Regrowth {
  std::vector<TreeEstimate> clusters;
  std::vector<int> cluster_of;  // per row, -1 before it joins a tree
  std::unordered_map<int64_t, std::vector<int>> grid;

  static int64_t Cell(const Eigen::Vector3d& p) {
    return (static_cast<int64_t>(std::floor(p.x())) << 32) ^
           static_cast<int64_t>(static_cast<uint32_t>(static_cast<int64_t>(std::floor(p.y()))));
  }
  // Row `r` joins tree `cluster`, which moves to its new cell if its position changed cells.
  void Add(int cluster, size_t r, const TreeObservation& row, const MergeOptions& options) {
    const int64_t before = Cell(clusters[cluster].position);
    AddObservation(clusters[cluster], row, options);
    cluster_of[r] = cluster;
    const int64_t after = Cell(clusters[cluster].position);
    if (before == after && clusters[cluster].observations > 1) return;
    if (clusters[cluster].observations > 1) std::erase(grid[before], cluster);
    grid[after].push_back(cluster);
  }
  // Row `r` starts a tree of its own.
  void AddNew(size_t r, const TreeObservation& row, const MergeOptions& options) {
    clusters.emplace_back();
    Add(static_cast<int>(clusters.size()) - 1, r, row, options);
  }
  // Appends the trees in the cells within `reach` cells of `p` to `seen` (with repeats).
  void Near(const Eigen::Vector3d& p, int reach, std::vector<int>& seen) const {
    for (int dx = -reach; dx <= reach; ++dx) {
      for (int dy = -reach; dy <= reach; ++dy) {
        const auto it = grid.find(Cell(p + Eigen::Vector3d(dx, dy, 0)));
        if (it != grid.end()) seen.insert(seen.end(), it->second.begin(), it->second.end());
      }
    }
  }
};

class Consolidator {
 public:
  // `rows` in any order; `tree_ids` must hold every tree id the rows refer to.
  Consolidator(std::vector<TreeObservation> rows, std::vector<int64_t> tree_ids,
               const MergeOptions& options)
      : options_(options), rows_(std::move(rows)), ids_(std::move(tree_ids)) {
    std::stable_sort(rows_.begin(), rows_.end(), CanonicalLess);
    std::sort(ids_.begin(), ids_.end());
    ids_.erase(std::unique(ids_.begin(), ids_.end()), ids_.end());
    for (size_t i = 0; i < ids_.size(); ++i) index_of_[ids_[i]] = static_cast<int>(i);
    owner_.resize(rows_.size());
    for (size_t r = 0; r < rows_.size(); ++r) {
      const auto it = index_of_.find(rows_[r].tree_id);
      if (it == index_of_.end()) ThrowUnknownTree(rows_[r]);
      owner_[r] = it->second;
    }
    for (const TreeObservation& row : rows_) original_ids_.push_back(row.tree_id);
    Recompute();
  }

  // Forgets the current association: the rows are merged afresh, frame by frame in canonical
  // order (survey priors first, each its own tree), as MergeFrame would merge them into an empty
  // map. Each new tree takes the id most of its rows had (ties: the smaller), if still free in
  // `pool`; else a new id from the pool.
  void Restart(IdPool& pool) {
    Regrowth growth;
    growth.cluster_of.assign(rows_.size(), -1);
    // Rows that define their trees (survey priors, summaries) start them; those of one tree
    // (a prior not folded yet beside a summary) start one.
    std::unordered_map<int64_t, int> defined;
    for (size_t r = 0; r < rows_.size(); ++r) {
      if (!rows_[r].defines_tree()) continue;
      const auto [it, first] =
          defined.emplace(rows_[r].tree_id, static_cast<int>(growth.clusters.size()));
      if (first) {
        growth.AddNew(r, rows_[r], options_);
      } else {
        growth.Add(it->second, r, rows_[r], options_);
      }
    }
    for (size_t begin = 0; begin < rows_.size();) {
      size_t end = begin + 1;
      while (end < rows_.size() && SameFrame(rows_[end], rows_[begin])) ++end;
      RegrowFrame(begin, end, growth);
      begin = end;
    }
    const std::vector<int64_t> cluster_id = ClusterIds(growth, pool);
    for (size_t c = 0; c < growth.clusters.size(); ++c) ids_.push_back(cluster_id[c]);
    std::sort(ids_.begin(), ids_.end());
    ids_.erase(std::unique(ids_.begin(), ids_.end()), ids_.end());
    index_of_.clear();
    for (size_t i = 0; i < ids_.size(); ++i) index_of_[ids_[i]] = static_cast<int>(i);
    for (size_t r = 0; r < rows_.size(); ++r) {
      owner_[r] = index_of_.at(cluster_id[growth.cluster_of[r]]);
    }
    Recompute();
  }

  // Appends the surviving trees and the rows (with their trees) to `result`; with
  // `report_removed`, also the trees left without rows.
  void Run(ConsolidateResult& result, bool report_removed = true) {
    // Duplicates are looked for last, so the trees returned have been checked as they are.
    for (int sweep = 0; sweep < std::max(1, options_.consolidate_iterations); ++sweep) {
      const int moved = Reassociate();
      const int merged = MergeDuplicates();
      result.merged += merged;
      if (merged == 0 && moved == 0) break;
    }
    for (size_t t = 0; t < ids_.size(); ++t) {
      if (estimates_[t].observations > 0) {
        result.trees.push_back(estimates_[t]);
      } else if (report_removed) {
        result.removed_ids.push_back(ids_[t]);
      }
    }
    for (size_t r = 0; r < rows_.size(); ++r) {
      rows_[r].tree_id = ids_[owner_[r]];
      if (rows_[r].tree_id != original_ids_[r]) ++result.reassigned;
    }
    result.observations.insert(result.observations.end(), std::make_move_iterator(rows_.begin()),
                               std::make_move_iterator(rows_.end()));
    rows_.clear();
  }

 private:
  // Merges the non-prior rows of one frame (rows_[begin, end)) into the trees grown so far, as
  // MergeFrame would: associated one-to-one with the trees near them, the rest new trees.
  void RegrowFrame(size_t begin, size_t end, Regrowth& growth) const {
    const int reach = static_cast<int>(std::ceil(options_.gate_distance));
    std::vector<TreeObservation> frame_rows;
    std::vector<size_t> frame_index;
    std::vector<int> seen;
    for (size_t r = begin; r < end; ++r) {
      if (rows_[r].defines_tree()) continue;
      frame_rows.push_back(rows_[r]);
      frame_index.push_back(r);
      growth.Near(rows_[r].position, reach, seen);
    }
    std::sort(seen.begin(), seen.end());
    seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
    std::vector<TreeEstimate> nearby;
    for (int c : seen) {
      nearby.push_back(growth.clusters[c]);
      nearby.back().id = c;  // ties broken by creation order
    }
    const internal::Association association =
        internal::AssociateGreedy(nearby, frame_rows, options_);
    for (size_t k = 0; k < frame_rows.size(); ++k) {
      const size_t r = frame_index[k];
      if (association.tree[k] >= 0) {
        growth.Add(seen[association.tree[k]], r, rows_[r], options_);
      } else {
        growth.AddNew(r, rows_[r], options_);
      }
    }
  }

  // Ids of the grown trees, in creation order: a summarized tree keeps its id (its folded rows
  // refer to it); another takes the most common previous id of its rows (ties: the smaller) if
  // still free in `pool`, else a new id from the pool.
  std::vector<int64_t> ClusterIds(const Regrowth& growth, IdPool& pool) const {
    std::vector<std::map<int64_t, int>> votes(growth.clusters.size());
    std::vector<int64_t> cluster_id(growth.clusters.size(), 0);
    std::vector<char> summarized(growth.clusters.size(), 0);
    for (size_t r = 0; r < rows_.size(); ++r) {
      ++votes[growth.cluster_of[r]][original_ids_[r]];
      if (!rows_[r].summary) continue;
      cluster_id[growth.cluster_of[r]] = rows_[r].tree_id;
      summarized[growth.cluster_of[r]] = 1;
    }
    for (size_t c = 0; c < growth.clusters.size(); ++c) {
      if (summarized[c]) {
        pool.taken.insert(cluster_id[c]);
        continue;
      }
      int best = 0;
      for (const auto& [id, n] : votes[c]) {
        if (n > best && pool.Free(id)) cluster_id[c] = id, best = n;
      }
      if (best == 0) {
        while (!pool.Free(pool.next_free_id)) ++pool.next_free_id;
        cluster_id[c] = pool.next_free_id++;
      }
      pool.taken.insert(cluster_id[c]);
    }
    return cluster_id;
  }

  void Recompute() {
    estimates_.assign(ids_.size(), TreeEstimate{});
    for (size_t t = 0; t < ids_.size(); ++t) estimates_[t].id = ids_[t];
    for (size_t r = 0; r < rows_.size(); ++r) {
      AddObservation(estimates_[owner_[r]], rows_[r], options_);
    }
  }

  // Frames (by row range) that observed each tree, to keep apart two stems seen in one frame.
  std::vector<std::vector<int>> FramesOfTrees() const {
    std::vector<std::vector<int>> frames(ids_.size());
    int frame = -1;
    for (size_t r = 0; r < rows_.size(); ++r) {
      if (r == 0 || !SameFrame(rows_[r], rows_[r - 1])) ++frame;
      if (!rows_[r].summary) frames[owner_[r]].push_back(frame);  // summaries: no frame
    }
    return frames;
  }

  // Pairs of live trees within duplicate_distance as (distance^2, tree a, tree b), a < b, closest
  // first; equal distances in the canonical order of the trees' first rows (not by id: ids
  // depend on the order in which rows arrived).
  std::vector<std::tuple<double, int, int>> ClosePairs() const {
    std::vector<TreeEstimate> live;
    std::vector<int> live_index;
    for (size_t t = 0; t < ids_.size(); ++t) {
      if (estimates_[t].observations == 0) continue;
      live.push_back(estimates_[t]);
      live_index.push_back(static_cast<int>(t));
    }
    std::vector<std::tuple<double, int, int>> pairs;
    if (live.size() < 2 || options_.duplicate_distance <= 0) return pairs;
    const auto kd = internal::BuildTreeIndex(live);
    std::vector<std::pair<uint32_t, double>> near;
    for (size_t i = 0; i < live.size(); ++i) {
      kd->Radius({live[i].position.x(), live[i].position.y()}, options_.duplicate_distance, near);
      for (const auto& [j, d2] : near) {
        if (j > i) pairs.emplace_back(d2, live_index[i], live_index[j]);
      }
    }
    std::vector<size_t> first_row(ids_.size(), rows_.size());
    for (size_t r = rows_.size(); r-- > 0;) first_row[owner_[r]] = r;
    std::sort(pairs.begin(), pairs.end(), [&first_row](const auto& p, const auto& q) {
      const auto key = [&first_row](const std::tuple<double, int, int>& t) {
        const size_t a = first_row[std::get<1>(t)], b = first_row[std::get<2>(t)];
        return std::make_tuple(std::get<0>(t), std::min(a, b), std::max(a, b));
      };
      return key(p) < key(q);
    });
    return pairs;
  }

  // One stem or two? Two stems are seen side by side in the frames that see either (the
  // association is one-to-one per frame); one stem whose DBH fits disagree (partial arcs shift
  // the centre) never is. Overlapping stems are one whatever the frames say. Two fixed trees
  // (surveyed or summarized) stay two. Side by side: at least min_shared_frames frames, and more
  // than max_shared_frames of the fewer frames of the two, see both (two frames that split a stem
  // into two detections 0.4 m apart do not make two trees).
  bool OneStem(int a, int b, double d2, const std::vector<std::vector<int>>& frames) const {
    const TreeEstimate& ta = estimates_[a];
    const TreeEstimate& tb = estimates_[b];
    if ((ta.surveyed || ta.summarized) && (tb.surveyed || tb.summarized)) return false;
    const double d = std::sqrt(d2);
    const bool overlap = IsKnown(ta.dbh) && IsKnown(tb.dbh) && d < 0.5 * (ta.dbh + tb.dbh);
    std::vector<int> common;
    std::set_intersection(frames[a].begin(), frames[a].end(), frames[b].begin(), frames[b].end(),
                          std::back_inserter(common));
    const double smaller = static_cast<double>(std::min(frames[a].size(), frames[b].size()));
    const bool side_by_side = static_cast<int>(common.size()) >= options_.min_shared_frames &&
                              common.size() > options_.max_shared_frames * smaller;
    return overlap || !side_by_side;
  }

  // Merges the pairs of trees that are one stem, closest first, one merge per tree; returns the
  // merges.
  int MergeDuplicates() {
    const std::vector<std::tuple<double, int, int>> pairs = ClosePairs();
    if (pairs.empty()) return 0;
    const std::vector<std::vector<int>> frames = FramesOfTrees();
    std::vector<int> root(ids_.size());
    std::iota(root.begin(), root.end(), 0);
    int merged = 0;
    for (const auto& [d2, a, b] : pairs) {
      if (root[a] != a || root[b] != b) continue;  // one merge per tree and sweep
      if (!OneStem(a, b, d2, frames)) continue;
      // ids_ is sorted: the smaller id survives, unless the other is summarized (its folded
      // rows refer to its id).
      const bool keep_b = estimates_[b].summarized && !estimates_[a].summarized;
      const int survivor = keep_b ? b : a;
      root[keep_b ? a : b] = survivor;
      root[survivor] = -1 - survivor;
      ++merged;
    }
    if (merged == 0) return 0;
    for (int& owner : owner_) {
      if (root[owner] >= 0 && root[owner] != owner) owner = root[owner];
    }
    Recompute();
    return merged;
  }

  int Reassociate() {
    // Equal costs are broken by the trees' first canonical rows, not by their ids (which depend
    // on the order in which rows arrived).
    std::vector<size_t> first_row(ids_.size(), rows_.size());
    for (size_t r = rows_.size(); r-- > 0;) first_row[owner_[r]] = r;
    std::vector<TreeEstimate> live;
    std::vector<int> live_index;
    for (size_t t = 0; t < ids_.size(); ++t) {
      if (estimates_[t].observations == 0) continue;
      live.push_back(estimates_[t]);
      live.back().id = static_cast<int64_t>(first_row[t]);
      live_index.push_back(static_cast<int>(t));
    }
    if (live.empty()) return 0;
    const auto kd = internal::BuildTreeIndex(live);
    int moved = 0;
    size_t begin = 0;
    std::vector<TreeObservation> frame_rows;
    std::vector<size_t> frame_index;
    while (begin < rows_.size()) {
      size_t end = begin + 1;
      while (end < rows_.size() && SameFrame(rows_[end], rows_[begin])) ++end;
      frame_rows.clear();
      frame_index.clear();
      for (size_t r = begin; r < end; ++r) {
        if (rows_[r].defines_tree()) continue;  // a survey prior or a summary defines its tree
        frame_rows.push_back(rows_[r]);
        frame_index.push_back(r);
      }
      const internal::Association association =
          internal::AssociateGreedy(live, *kd, frame_rows, options_);
      for (size_t k = 0; k < frame_rows.size(); ++k) {
        const int assigned = association.tree[k];
        if (assigned < 0) continue;  // keeps its tree: no estimate explains it better
        const int owner = live_index[assigned];
        if (owner_[frame_index[k]] != owner) {
          owner_[frame_index[k]] = owner;
          ++moved;
        }
      }
      begin = end;
    }
    if (moved > 0) Recompute();
    return moved;
  }

  const MergeOptions& options_;
  std::vector<TreeObservation> rows_;
  std::vector<int64_t> ids_;  // sorted
  std::unordered_map<int64_t, int> index_of_;
  std::vector<int> owner_;             // per row, index into ids_
  std::vector<int64_t> original_ids_;  // per row, its tree before
  std::vector<TreeEstimate> estimates_;
};

std::vector<int64_t> IdsOf(std::span<const TreeEstimate> trees) {
  std::vector<int64_t> ids;
  for (const TreeEstimate& tree : trees) ids.push_back(tree.id);
  return ids;
}

}  // namespace

ConsolidateResult ConsolidateTrees(std::span<const TreeEstimate> trees,
                                   std::span<const TreeObservation> observations,
                                   const MergeOptions& options) {
  options.Check();
  ConsolidateResult result;
  Consolidator consolidator({observations.begin(), observations.end()}, IdsOf(trees), options);
  consolidator.Run(result);
  return result;
}

ConsolidateResult RebuildTrees(std::span<const TreeEstimate> trees,
                               std::span<const TreeObservation> observations, int64_t next_free_id,
                               const MergeOptions& options) {
  options.Check();
  const std::vector<int64_t> given = IdsOf(trees);
  const std::unordered_set<int64_t> known(given.begin(), given.end());
  std::vector<TreeObservation> rows(observations.begin(), observations.end());
  for (const TreeObservation& row : rows) {
    if (known.count(row.tree_id) == 0) ThrowUnknownTree(row);
  }
  std::stable_sort(rows.begin(), rows.end(), CanonicalLess);
  // Components numbered by their first canonical row: a canonical order of components too.
  const std::vector<int> component = ObservationComponents(rows, options);
  const int count = rows.empty() ? 0 : *std::max_element(component.begin(), component.end()) + 1;
  std::vector<std::vector<TreeObservation>> parts(count);
  for (size_t r = 0; r < rows.size(); ++r) parts[component[r]].push_back(std::move(rows[r]));
  ConsolidateResult result;
  IdPool pool{next_free_id, {}, {}};
  for (const std::vector<TreeObservation>& part : parts) {
    for (const TreeObservation& row : part) {
      if (row.summary) pool.reserved.insert(row.tree_id);
    }
  }
  for (std::vector<TreeObservation>& part : parts) {
    std::vector<int64_t> ids;
    for (const TreeObservation& row : part) ids.push_back(row.tree_id);
    Consolidator consolidator(std::move(part), std::move(ids), options);
    consolidator.Restart(pool);
    consolidator.Run(result, /*report_removed=*/false);
  }
  std::unordered_set<int64_t> kept;
  for (const TreeEstimate& tree : result.trees) kept.insert(tree.id);
  for (const int64_t id : given) {
    if (kept.count(id) == 0) result.removed_ids.push_back(id);
  }
  std::sort(result.removed_ids.begin(), result.removed_ids.end());
  result.removed_ids.erase(std::unique(result.removed_ids.begin(), result.removed_ids.end()),
                           result.removed_ids.end());
  std::sort(result.trees.begin(), result.trees.end(),
            [](const TreeEstimate& a, const TreeEstimate& b) { return a.id < b.id; });
  return result;
}

}  // namespace forestmap::algorithms
