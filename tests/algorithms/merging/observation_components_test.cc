// Connected components of observation rows (algorithms/merging/observation_components.h) against a
// brute-force union of every pair closer than the link distance, in any insertion order.
#include "algorithms/merging/observation_components.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>
#include <vector>

namespace forestmap::algorithms {
namespace {

// Clumps of points around "stems" 1-3 m apart, with strays between them, some exactly on grid
// lines of the linker's cells, and negative coordinates.
std::vector<Eigen::Vector2d> Points(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> where(-20, 20), spread(-0.25, 0.25);
  std::vector<Eigen::Vector2d> points;
  for (int stem = 0; stem < 80; ++stem) {
    const Eigen::Vector2d center(where(rng), where(rng));
    for (int k = 0; k < 8; ++k) {
      points.push_back(center + Eigen::Vector2d(spread(rng), spread(rng)));
    }
  }
  // A chain of points exactly 0.5 m apart (binary fractions: the distances are exact).
  for (int k = 0; k < 20; ++k) points.push_back(Eigen::Vector2d(0.5 * k - 6, -1.5));
  points.push_back(Eigen::Vector2d(4.0, -1.5));  // exactly 0.5 m beyond the chain's end
  return points;
}

// Component labels as a canonical partition: each point's label is its component's first point.
std::vector<int> Canonical(const std::vector<int>& root) {
  std::map<int, int> first;
  std::vector<int> out(root.size());
  for (size_t i = 0; i < root.size(); ++i) {
    out[i] = first.try_emplace(root[i], static_cast<int>(i)).first->second;
  }
  return out;
}

std::vector<int> BruteForce(const std::vector<Eigen::Vector2d>& points, double link) {
  std::vector<int> label(points.size());
  std::iota(label.begin(), label.end(), 0);
  for (bool changed = true; changed;) {  // relax until every linked pair agrees
    changed = false;
    for (size_t i = 0; i < points.size(); ++i) {
      for (size_t j = 0; j < points.size(); ++j) {
        if ((points[i] - points[j]).squaredNorm() > link * link) continue;
        const int low = std::min(label[i], label[j]);
        if (label[i] != low || label[j] != low) label[i] = label[j] = low, changed = true;
      }
    }
  }
  return Canonical(label);
}

TEST(ObservationComponents, EqualsTheBruteForceUnionInAnyInsertionOrder) {
  constexpr double kLink = 0.5;  // m
  const std::vector<Eigen::Vector2d> points = Points(5);
  const std::vector<int> truth = BruteForce(points, kLink);
  EXPECT_EQ(truth[points.size() - 1], truth[points.size() - 21]);  // <= links at exactly 0.5 m
  std::vector<int> order(points.size());
  std::iota(order.begin(), order.end(), 0);
  std::mt19937 rng(7);
  for (int trial = 0; trial < 3; ++trial) {
    ObservationLinker linker(kLink);
    std::vector<int> index_of(points.size());
    for (const int i : order) index_of[i] = linker.Add(points[i]);
    std::vector<int> root(points.size());
    for (size_t i = 0; i < points.size(); ++i) root[i] = linker.Root(index_of[i]);
    EXPECT_EQ(Canonical(root), truth) << "trial " << trial;
    std::shuffle(order.begin(), order.end(), rng);
  }
  // The row interface numbers components by their first row.
  std::vector<TreeObservation> rows(points.size());
  for (size_t i = 0; i < points.size(); ++i) rows[i].position.head<2>() = points[i];
  MergeOptions options;
  options.gate_distance = kLink;
  const std::vector<int> component = ObservationComponents(rows, options);
  EXPECT_EQ(Canonical(component), truth);
  EXPECT_EQ(component[0], 0);
  EXPECT_EQ(*std::max_element(component.begin(), component.end()) + 1,
            static_cast<int>(std::set<int>(truth.begin(), truth.end()).size()));
}

TEST(ObservationComponents, RejectsANonPositiveLinkDistance) {
  EXPECT_THROW(ObservationLinker(0.0), std::invalid_argument);
  EXPECT_THROW(ObservationLinker(std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
