#include "algorithms/tree_adjustment.h"

#include <map>
#include <stdexcept>
#include <string>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

namespace forestmap::algorithms {

void TreeAdjustmentOptions::Check() const {
  if (iterations < 1) throw std::invalid_argument("TreeAdjustmentOptions.iterations must be >= 1");
  if (!(huber > 0)) throw std::invalid_argument("TreeAdjustmentOptions.huber must be > 0 m");
  if (max_tree_observations < 2) {
    throw std::invalid_argument("TreeAdjustmentOptions.max_tree_observations must be >= 2");
  }
}

namespace {

struct Term {
  Eigen::Vector2d residual;   // R q + t - m
  Eigen::Matrix<double, 2, 3> jacobian;  // w.r.t. (x, y, yaw); w.r.t. m it is -I
  double weight = 0;          // observation weight x robust weight
};

Term Evaluate(const Pose4& pose, const Eigen::Vector2d& tree,
              const TreeAdjustmentObservation& o, double huber) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  const Eigen::Vector2d rq(c * o.level_xy.x() - s * o.level_xy.y(),
                           s * o.level_xy.x() + c * o.level_xy.y());
  Term term;
  term.residual = rq + pose.translation.head<2>() - tree;
  term.jacobian << 1, 0, -rq.y(), 0, 1, rq.x();
  const double r = term.residual.norm();
  term.weight = o.weight * (r <= huber ? 1.0 : huber / r);
  return term;
}

double WeightedRms(const std::vector<Pose4>& poses, const std::vector<Eigen::Vector2d>& trees,
                   const std::vector<TreeAdjustmentObservation>& observations) {
  double sum = 0, w = 0;
  for (const auto& o : observations) {
    const Term t = Evaluate(poses[o.frame], trees[o.tree], o, 1e9);
    sum += o.weight * t.residual.squaredNorm();
    w += o.weight;
  }
  return w > 0 ? std::sqrt(sum / w) : 0;
}

}  // namespace

TreeAdjustmentResult AdjustTrees(std::vector<Pose4> poses, std::vector<Eigen::Vector2d> trees,
                                 const std::vector<TreeAdjustmentObservation>& observations,
                                 const TreeAdjustmentOptions& options) {
  options.Check();
  const int n = static_cast<int>(poses.size());
  std::vector<std::vector<int>> by_tree(trees.size());
  for (size_t k = 0; k < observations.size(); ++k) {
    const auto& o = observations[k];
    if (o.frame < 0 || o.frame >= n || o.tree < 0 || o.tree >= static_cast<int>(trees.size())) {
      throw std::invalid_argument("tree adjustment observation " + std::to_string(k) +
                                  " names frame " + std::to_string(o.frame) + " / tree " +
                                  std::to_string(o.tree) + ", out of range");
    }
    by_tree[o.tree].push_back(static_cast<int>(k));
  }
  // The reduced system costs O(n^2) per tree seen n times: keep an even subset of the views.
  for (std::vector<int>& rows : by_tree) {
    const size_t n = rows.size(), cap = static_cast<size_t>(options.max_tree_observations);
    if (n <= cap) continue;
    std::vector<int> kept;
    for (size_t i = 0; i < cap; ++i) kept.push_back(rows[i * n / cap]);
    rows = std::move(kept);
  }
  TreeAdjustmentResult result;
  result.initial_rms = WeightedRms(poses, trees, observations);
  for (int iteration = 0; iteration < options.iterations; ++iteration) {
    // Reduced system S dp = -g over the poses, trees eliminated one 2x2 block at a time.
    std::map<std::pair<int, int>, Eigen::Matrix3d> blocks;
    auto block = [&blocks](int a, int b) -> Eigen::Matrix3d& {
      const auto [it, inserted] = blocks.try_emplace({a, b});
      if (inserted) it->second.setZero();  // Eigen leaves new matrices uninitialised
      return it->second;
    };
    Eigen::VectorXd gradient = Eigen::VectorXd::Zero(3 * n);
    std::vector<Term> terms;
    for (size_t j = 0; j < trees.size(); ++j) {
      if (by_tree[j].size() < 2) continue;
      terms.clear();
      double w_sum = 0;
      Eigen::Vector2d g_tree = Eigen::Vector2d::Zero();  // d cost / d m (J_m = -I)
      for (int k : by_tree[j]) {
        const auto& o = observations[k];
        terms.push_back(Evaluate(poses[o.frame], trees[j], o, options.huber));
        w_sum += terms.back().weight;
        g_tree -= terms.back().weight * terms.back().residual;
      }
      for (size_t a = 0; a < terms.size(); ++a) {
        const int fa = observations[by_tree[j][a]].frame;
        const Term& ta = terms[a];
        gradient.segment<3>(3 * fa) += ta.weight * ta.jacobian.transpose() * ta.residual;
        // g_p -= H_pm H_mm^-1 g_m with H_pm = -w J^T, H_mm = w_sum I.
        gradient.segment<3>(3 * fa) += ta.weight * ta.jacobian.transpose() * g_tree / w_sum;
        block(fa, fa) += ta.weight * ta.jacobian.transpose() * ta.jacobian;
        for (size_t b = 0; b < terms.size(); ++b) {
          const int fb = observations[by_tree[j][b]].frame;
          if (fb < fa) continue;
          const Term& tb = terms[b];
          block(fa, fb) -= (ta.weight * tb.weight / w_sum) * ta.jacobian.transpose() * tb.jacobian;
        }
      }
    }
    std::vector<Eigen::Triplet<double>> triplets;
    for (const auto& [key, b] : blocks) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
          triplets.emplace_back(3 * key.first + r, 3 * key.second + c, b(r, c));
          if (key.first != key.second) {
            triplets.emplace_back(3 * key.second + c, 3 * key.first + r, b(r, c));
          }
        }
      }
    }
    for (int k = 0; k < 3 * n; ++k) triplets.emplace_back(k, k, k < 3 ? 1e12 : 1e-6);
    Eigen::SparseMatrix<double> s(3 * n, 3 * n);
    s.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(s);
    if (solver.info() != Eigen::Success) break;
    const Eigen::VectorXd step = solver.solve(-gradient);
    for (int i = 0; i < n; ++i) {
      poses[i].translation.head<2>() += step.segment<2>(3 * i);
      poses[i].yaw = WrapAngle(poses[i].yaw + step(3 * i + 2));
    }
    // Trees: the weighted mean of their observations under the new poses.
    for (size_t j = 0; j < trees.size(); ++j) {
      if (by_tree[j].empty()) continue;
      Eigen::Vector2d sum = Eigen::Vector2d::Zero();
      double w = 0;
      for (int k : by_tree[j]) {
        const auto& o = observations[k];
        const Term t = Evaluate(poses[o.frame], trees[j], o, options.huber);
        sum += t.weight * (t.residual + trees[j]);
        w += t.weight;
      }
      trees[j] = sum / w;
    }
    result.iterations = iteration + 1;
  }
  result.final_rms = WeightedRms(poses, trees, observations);
  result.poses = std::move(poses);
  result.trees = std::move(trees);
  return result;
}

}  // namespace forestmap::algorithms
