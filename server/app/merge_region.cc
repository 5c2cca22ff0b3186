#include "server/app/merge_region.h"

#include <algorithm>
#include <set>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "algorithms/merging/observation_components.h"
#include "server/app/tree_records.h"

namespace forestmap::server {
namespace {

using storage::ObservationCell;

// Every cell that holds a point within `reach` m (per axis) of p.
void AddCellsAround(const Eigen::Vector3d& p, double reach, std::set<ObservationCell>& cells) {
  const ObservationCell low = storage::CellOf(p.x() - reach, p.y() - reach);
  const ObservationCell high = storage::CellOf(p.x() + reach, p.y() + reach);
  for (int64_t x = low.x; x <= high.x; ++x) {
    for (int64_t y = low.y; y <= high.y; ++y) cells.insert({x, y});
  }
}

// The box covering `cells` (inclusive edges).
storage::Extent BoxOf(const std::set<ObservationCell>& cells) {
  const double size = storage::kObservationCellSize;
  storage::Extent box{cells.begin()->x * size, cells.begin()->y * size, 0, 0};
  box.max_x = box.min_x, box.max_y = box.min_y;
  for (const ObservationCell& cell : cells) {
    box.min_x = std::min(box.min_x, cell.x * size);
    box.min_y = std::min(box.min_y, cell.y * size);
    box.max_x = std::max(box.max_x, (cell.x + 1) * size);
    box.max_y = std::max(box.max_y, (cell.y + 1) * size);
  }
  return box;
}

// Grows the region round by round. Points are the seeds, then loaded rows and unsaved priors,
// linked as they come (algorithms::ObservationLinker with the merge's link distance, the one
// RebuildTrees partitions by).
class RegionLoader {
 public:
  RegionLoader(storage::MergeReader& reader, std::span<const algorithms::TreeObservation> seeds,
               const algorithms::MergeOptions& options)
      : reader_(reader), options_(options), seeds_(seeds.size()), linker_(options.gate_distance) {
    for (const algorithms::TreeObservation& seed : seeds) {
      AddPoint(seed, Kind::kSeed, 0);
    }
  }

  MergeRegion Run() {
    MergeRegion region;
    std::set<ObservationCell> cells;
    for (size_t p = 0; p < seeds_; ++p) {
      AddCellsAround(position_[p], options_.gate_distance, cells);
    }
    std::vector<int64_t> trees;
    while (!cells.empty() || !trees.empty()) {
      ++region.iterations;
      Load(cells, trees);
      cells.clear();
      trees.clear();
      const std::vector<char> in_region = InRegion();
      for (size_t p = 0; p < kind_.size(); ++p) {
        if (!in_region[p]) continue;
        AddCellsAround(position_[p], options_.gate_distance, cells);
        if (kind_[p].first != Kind::kRow) continue;
        const int64_t tree = rows_[kind_[p].second].tree_id;
        if (!rows_complete_.insert(tree).second) continue;
        // The tree record counts its rows: when all are here already, there is no need to ask.
        const auto record = trees_.find(tree);
        if (record == trees_.end() || record->second.observations > rows_of_tree_[tree]) {
          trees.push_back(tree);
        }
      }
      std::erase_if(cells, [&](const ObservationCell& c) { return loaded_cells_.count(c) != 0; });
      if (cells.empty() && trees.empty()) Collect(in_region, region);
    }
    return region;
  }

 private:
  enum class Kind { kSeed, kRow, kPrior };

  void AddPoint(const algorithms::TreeObservation& row, Kind kind, size_t index) {
    linker_.Add(row.position.head<2>());
    position_.push_back(row.position);
    kind_.emplace_back(kind, index);
  }

  // Rows of one tree are kept in one region (a tree may span components: rows stored before
  // the rebuild by components, or split by a source removal).
  void AddRows(std::vector<storage::ObservationRecord> rows) {
    for (storage::ObservationRecord& row : rows) {
      if (!row_ids_.insert(row.id).second) continue;
      const algorithms::TreeObservation observation = ToTreeObservation(row);
      // A summary row stands for the folded rows of its tree (its tree record counts them).
      rows_of_tree_[row.tree_id] += observation.summary ? observation.summary->rows : 1;
      const int point = static_cast<int>(kind_.size());
      AddPoint(observation, Kind::kRow, rows_.size());
      const auto [first, inserted] = first_point_of_tree_.emplace(row.tree_id, point);
      if (!inserted) linker_.Link(first->second, point);
      rows_.push_back(std::move(row));
    }
  }

  // Rows in `cells`, surveyed trees without rows there (and the records of the other trees
  // there), and every row of `trees`.
  void Load(const std::set<ObservationCell>& cells, const std::vector<int64_t>& trees) {
    if (!cells.empty()) {
      const std::vector<ObservationCell> list(cells.begin(), cells.end());
      AddRows(reader_.ObservationsInCells(list));
      for (storage::TreeRecord& tree : reader_.TreesInBox(BoxOf(cells))) {
        const ObservationCell cell = storage::CellOf(tree.x, tree.y);
        if (cells.count(cell) == 0) continue;  // outside the cells: loaded with its own cell
        const int64_t id = *tree.id;
        // A tree record counts the rows behind it: none means a survey tree nobody observed.
        if (tree.observations == 0) {
          algorithms::TreeObservation prior =
              algorithms::SurveyObservation(ToMapTree(tree), options_);
          prior.tree_id = id;
          AddPoint(prior, Kind::kPrior, priors_.size());
          priors_.push_back(std::move(prior));
        }
        trees_.emplace(id, std::move(tree));
      }
      loaded_cells_.insert(cells.begin(), cells.end());
    }
    if (!trees.empty()) AddRows(reader_.ObservationsOfTrees(trees));
  }

  // Points in a component that holds a seed.
  std::vector<char> InRegion() {
    std::unordered_set<int> seeded;
    for (size_t p = 0; p < seeds_; ++p) seeded.insert(linker_.Root(static_cast<int>(p)));
    std::vector<char> in_region(kind_.size(), 0);
    for (size_t p = 0; p < kind_.size(); ++p) {
      in_region[p] = seeded.count(linker_.Root(static_cast<int>(p))) != 0;
    }
    return in_region;
  }

  void Collect(const std::vector<char>& in_region, MergeRegion& region) {
    std::set<int64_t> tree_ids;
    for (size_t p = seeds_; p < kind_.size(); ++p) {
      const auto [kind, index] = kind_[p];
      if (!in_region[p]) {
        if (kind == Kind::kRow)
          region.foldable_outside[rows_[index].tree_id].push_back(rows_[index]);
        continue;
      }
      if (kind == Kind::kRow) {
        region.rows.push_back(rows_[index]);
        tree_ids.insert(rows_[index].tree_id);
      } else {
        region.unsaved_priors.push_back(priors_[index]);
        tree_ids.insert(priors_[index].tree_id);
      }
    }
    std::sort(region.rows.begin(), region.rows.end(),
              [](const auto& a, const auto& b) { return a.id < b.id; });
    std::vector<int64_t> missing;
    for (const int64_t id : tree_ids) {
      const auto it = trees_.find(id);
      if (it == trees_.end()) {
        missing.push_back(id);
      } else {
        region.trees.emplace(id, it->second);
      }
    }
    for (storage::TreeRecord& tree : reader_.TreesById(missing)) {
      region.trees.emplace(*tree.id, std::move(tree));
    }
    // Outside: only trees whose record counts exactly the rows loaded, enough to fold.
    std::erase_if(region.foldable_outside, [&](const auto& entry) {
      const auto record = trees_.find(entry.first);
      return record == trees_.end() || record->second.observations != rows_of_tree_[entry.first] ||
             static_cast<int>(entry.second.size()) <= options_.fold_rows;
    });
  }

  storage::MergeReader& reader_;
  const algorithms::MergeOptions& options_;
  const size_t seeds_;
  algorithms::ObservationLinker linker_;
  // Per point (seeds first): its position and what it is (index in rows_ or priors_).
  std::vector<Eigen::Vector3d> position_;
  std::vector<std::pair<Kind, size_t>> kind_;
  std::vector<storage::ObservationRecord> rows_;
  std::vector<algorithms::TreeObservation> priors_;
  std::unordered_set<int64_t> row_ids_;
  std::set<ObservationCell> loaded_cells_;
  std::unordered_map<int64_t, int64_t> rows_of_tree_;     // loaded rows per tree
  std::unordered_map<int64_t, int> first_point_of_tree_;  // rows of a tree are linked to it
  std::unordered_set<int64_t> rows_complete_;             // trees whose rows are all loaded
  std::map<int64_t, storage::TreeRecord> trees_;          // records of trees seen so far
};

}  // namespace

MergeRegion LoadMergeRegion(storage::MergeReader& reader,
                            std::span<const algorithms::TreeObservation> seeds,
                            const algorithms::MergeOptions& options) {
  return RegionLoader(reader, seeds, options).Run();
}

}  // namespace forestmap::server
