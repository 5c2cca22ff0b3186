#include "algorithms/mapping/tree_adjustment.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace forestmap::algorithms {

void TreeAdjustmentOptions::Check() const {
  auto require = [](bool ok, const char* field) {
    if (!ok) throw std::invalid_argument(std::string("TreeAdjustmentOptions.") + field);
  };
  require(iterations >= 1, "iterations must be >= 1");
  require(cauchy_iterations >= 0 && cauchy_iterations <= iterations,
          "cauchy_iterations must be in [0, iterations]");
  require(huber_xy > 0 && cauchy_xy > 0 && cauchy_z > 0,
          "huber_xy, cauchy_xy, cauchy_z must be > 0 m");
  require(tolerance >= 0, "tolerance must be >= 0");
  require(max_tree_observations >= 2, "max_tree_observations must be >= 2");
}

namespace {

using Vector4 = Eigen::Vector4d;
using Jacobian = Eigen::Matrix<double, 3, 4>;  // residual (x, y, z) w.r.t. pose (x, y, z, yaw)

// Robust kernels on a residual r (m) with scale k: weight rho'(r^2) for IRLS and cost rho(r^2).
// Huber for the first steps (convex), then Cauchy.
struct Kernel {
  bool cauchy = false;
  double Weight(double r, double k) const {
    if (cauchy) return 1.0 / (1.0 + (r / k) * (r / k));
    return r <= k ? 1.0 : k / r;
  }
  double Cost(double r, double k) const {
    if (cauchy) return k * k * std::log1p((r / k) * (r / k));
    return r <= k ? r * r : k * (2 * r - k);
  }
};

struct Term {
  Eigen::Vector3d residual;  // R q + t - m
  Jacobian jacobian;         // w.r.t. the pose; w.r.t. the tree it is -I
  Eigen::Vector3d weight;    // per axis: observation weight x robust weight
  double cost = 0;           // robust, weighted
};

Term Evaluate(const Pose4& pose, const Eigen::Vector3d& tree, const TreeAdjustmentObservation& o,
              const Kernel& kernel, const TreeAdjustmentOptions& options) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  const Eigen::Vector3d& q = o.level_position;
  const Eigen::Vector2d rq(c * q.x() - s * q.y(), s * q.x() + c * q.y());
  Term term;
  term.residual.head<2>() = rq + pose.translation.head<2>() - tree.head<2>();
  term.jacobian << 1, 0, 0, -rq.y(), 0, 1, 0, rq.x(), 0, 0, 1, 0;
  const double r_xy = term.residual.head<2>().norm();
  const double scale = kernel.cauchy ? options.cauchy_xy : options.huber_xy;
  const double w_xy = o.weight_xy * kernel.Weight(r_xy, scale);
  term.weight = Eigen::Vector3d(w_xy, w_xy, 0);
  term.cost = o.weight_xy * kernel.Cost(r_xy, scale);
  term.residual.z() = q.z() + pose.translation.z() - tree.z();
  if (o.weight_z > 0 && std::isfinite(term.residual.z())) {
    // Heights are linear: least squares first (a unique start), then Cauchy.
    const double r_z = std::abs(term.residual.z());
    term.weight.z() = o.weight_z * (kernel.cauchy ? kernel.Weight(r_z, options.cauchy_z) : 1.0);
    term.cost += o.weight_z * (kernel.cauchy ? kernel.Cost(r_z, options.cauchy_z) : r_z * r_z);
  } else {
    term.residual.z() = 0;
  }
  return term;
}

// The reduced normal equations: a symmetric matrix of 4x4 pose blocks with a pattern fixed by
// which frames share trees, its lower triangle in one sparse matrix whose ordering and symbolic
// factorisation are computed once (SimplicialLDLT, AMD).
class BlockSystem {
 public:
  // `pairs`: blocks (a, b), a <= b, that may be non-zero (duplicates allowed).
  BlockSystem(int frames, std::vector<int64_t> pairs) : frames_(frames) {
    for (int i = 0; i < frames; ++i) pairs.push_back(Key(i, i));
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    keys_ = std::move(pairs);
    std::vector<Eigen::Triplet<double>> triplets;
    for (size_t slot = 0; slot < keys_.size(); ++slot) {
      const int a = static_cast<int>(keys_[slot] / frames_),
                b = static_cast<int>(keys_[slot] % frames_);
      for (int r = 0; r < 4; ++r) {
        for (int c = a == b ? r : 0; c < 4; ++c) {
          // Entry (r, c) of block (a, b) is stored transposed, at (4b + c, 4a + r).
          triplets.emplace_back(4 * b + c, 4 * a + r, static_cast<double>(entries_.size() + 1));
          entries_.push_back(static_cast<int>(slot * 16 + r * 4 + c));
        }
      }
    }
    matrix_.resize(4 * frames, 4 * frames);
    matrix_.setFromTriplets(triplets.begin(), triplets.end());
    // Where each entry landed: its value is still its ordinal.
    value_of_entry_.resize(entries_.size());
    for (Eigen::Index k = 0; k < matrix_.nonZeros(); ++k) {
      value_of_entry_[static_cast<size_t>(matrix_.valuePtr()[k]) - 1] = static_cast<int>(k);
    }
    solver_.analyzePattern(matrix_);
    blocks_.resize(keys_.size());
  }

  int Slot(int a, int b) const {
    return static_cast<int>(std::lower_bound(keys_.begin(), keys_.end(), Key(a, b)) -
                            keys_.begin());
  }
  void Zero() {
    for (Eigen::Matrix4d& block : blocks_) block.setZero();
  }
  Eigen::Matrix4d& Block(int slot) { return blocks_[slot]; }

  // Solves (S + lambda diag(S)) x = rhs with frame 0 held fixed; false when not positive.
  bool Solve(const Eigen::VectorXd& rhs, double lambda, Eigen::VectorXd& x) {
    double* values = matrix_.valuePtr();
    for (size_t e = 0; e < entries_.size(); ++e) {
      const int slot = entries_[e] / 16, r = entries_[e] % 16 / 4, c = entries_[e] % 4;
      const bool diagonal = keys_[slot] % (frames_ + 1) == 0 && r == c;  // a == b
      double v = blocks_[slot](r, c);
      if (diagonal) v = v * (1 + lambda) + (slot == 0 ? 1e12 : 1e-9);
      values[value_of_entry_[e]] = v;
    }
    solver_.factorize(matrix_);
    if (solver_.info() != Eigen::Success) return false;
    x = solver_.solve(rhs);
    return x.allFinite();
  }

 private:
  int64_t Key(int a, int b) const { return static_cast<int64_t>(a) * frames_ + b; }

  int frames_;
  std::vector<int64_t> keys_;        // sorted block keys a * frames + b
  std::vector<int> entries_;         // per stored entry: slot * 16 + r * 4 + c
  std::vector<int> value_of_entry_;  // per stored entry: index into the matrix's values
  std::vector<Eigen::Matrix4d> blocks_;
  Eigen::SparseMatrix<double> matrix_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver_;
};

class Adjuster {
 public:
  Adjuster(std::vector<Pose4> poses, std::vector<Eigen::Vector3d> trees,
           const std::vector<TreeAdjustmentObservation>& observations,
           const std::vector<PoseGraphEdge>& edges, const TreeAdjustmentOptions& options)
      : options_(options),
        observations_(observations),
        edges_(edges),
        poses_(std::move(poses)),
        trees_(std::move(trees)),
        by_tree_(trees_.size()) {
    const int n = static_cast<int>(poses_.size());
    for (size_t k = 0; k < observations.size(); ++k) {
      const auto& o = observations[k];
      if (o.frame < 0 || o.frame >= n || o.tree < 0 || o.tree >= static_cast<int>(trees_.size())) {
        throw std::invalid_argument("tree adjustment observation " + std::to_string(k) +
                                    " names frame " + std::to_string(o.frame) + " / tree " +
                                    std::to_string(o.tree) + ", out of range");
      }
      by_tree_[o.tree].push_back(static_cast<int>(k));
    }
    for (const PoseGraphEdge& e : edges) {
      if (e.from < 0 || e.from >= n || e.to < 0 || e.to >= n || e.from == e.to) {
        throw std::invalid_argument("tree adjustment edge names no pair of frames");
      }
    }
    // The reduced system costs O(n^2) per tree seen n times: keep an even subset of the views.
    for (std::vector<int>& rows : by_tree_) {
      const size_t size = rows.size(), cap = static_cast<size_t>(options.max_tree_observations);
      if (size <= cap) continue;
      std::vector<int> kept;
      for (size_t i = 0; i < cap; ++i) kept.push_back(rows[i * size / cap]);
      rows = std::move(kept);
    }
    // The pattern of the reduced system, and where each tree's and edge's terms go in it.
    std::vector<int64_t> keys;
    auto key = [n](int a, int b) {
      return static_cast<int64_t>(std::min(a, b)) * n + std::max(a, b);
    };
    for (const std::vector<int>& rows : by_tree_) {
      if (rows.size() < 2) continue;
      for (int ka : rows) {
        for (int kb : rows) {
          const int fa = observations[ka].frame, fb = observations[kb].frame;
          if (fb >= fa) keys.push_back(key(fa, fb));
        }
      }
    }
    for (const PoseGraphEdge& e : edges) keys.push_back(key(e.from, e.to));
    system_ = std::make_unique<BlockSystem>(n, std::move(keys));
    for (const std::vector<int>& rows : by_tree_) {
      if (rows.size() < 2) continue;
      for (int ka : rows) {
        for (int kb : rows) {
          const int fa = observations[ka].frame, fb = observations[kb].frame;
          if (fb >= fa) slots_.push_back(system_->Slot(fa, fb));
        }
      }
    }
    for (const PoseGraphEdge& e : edges) {
      const int from = std::min(e.from, e.to), to = std::max(e.from, e.to);
      edge_slots_.push_back(
          {system_->Slot(from, from), system_->Slot(to, to), system_->Slot(from, to)});
    }
  }

  // Levenberg-Marquardt: Huber steps first (convex: the result does not depend on the start),
  // then the optional Cauchy steps (bounded influence of wrong associations); heights are least
  // squares in the Huber steps. huber_xy is wide (2 m): the associations come gated (0.6 m), and
  // where they close a loop the residuals start large; a narrow kernel there keeps the loop open
  // (Wild_V01: ATE 0.13 m with 2 m, 0.21 m with a 0.15 m Cauchy kernel after 0.5 m Huber steps).
  TreeAdjustmentResult Run() {
    TreeAdjustmentResult result;
    const int huber_iterations = options_.iterations - options_.cauchy_iterations;
    Kernel kernel{huber_iterations == 0};
    UpdateTrees(kernel);
    result.initial_rms = Rms();
    result.initial_cost = Cost(Kernel{});
    double lambda = 1e-4;
    for (int iteration = 0; iteration < options_.iterations; ++iteration) {
      kernel.cauchy = iteration >= huber_iterations;
      const double cost = Cost(kernel);
      const std::vector<Pose4> poses = poses_;
      const std::vector<Eigen::Vector3d> trees = trees_;
      const Eigen::VectorXd gradient = Build(kernel);
      double next = cost;
      bool accepted = false;
      for (int attempt = 0; attempt < 5 && !accepted; ++attempt) {
        if (!Step(gradient, lambda)) break;
        UpdateTrees(kernel);
        next = Cost(kernel);
        accepted = next <= cost;
        lambda = accepted ? std::max(1e-8, lambda / 10) : lambda * 10;
        if (!accepted) poses_ = poses, trees_ = trees;
      }
      if (accepted) ++result.iterations;
      const bool converged = !accepted || cost - next <= options_.tolerance * cost;
      if (converged && (kernel.cauchy || options_.cauchy_iterations == 0)) break;
      if (converged) iteration = std::max(iteration, huber_iterations - 1);
    }
    result.final_rms = Rms();
    result.final_cost = Cost(Kernel{});
    result.poses = std::move(poses_);
    result.trees = std::move(trees_);
    return result;
  }

 private:
  // Reduced normal equations over the poses, the trees eliminated one block at a time:
  // S = H_pp - H_pm H_mm^-1 H_mp, g = g_p - H_pm H_mm^-1 g_m, with H_mm = diag(sum w).
  Eigen::VectorXd Build(const Kernel& kernel) {
    system_->Zero();
    Eigen::VectorXd gradient = Eigen::VectorXd::Zero(4 * poses_.size());
    std::vector<Term> terms;
    const int* slot = slots_.data();
    for (size_t j = 0; j < trees_.size(); ++j) {
      const std::vector<int>& rows = by_tree_[j];
      if (rows.size() < 2) continue;
      terms.clear();
      Eigen::Vector3d w_sum = Eigen::Vector3d::Zero(), g_tree = Eigen::Vector3d::Zero();
      for (int k : rows) {
        const auto& o = observations_[k];
        terms.push_back(Evaluate(poses_[o.frame], trees_[j], o, kernel, options_));
        w_sum += terms.back().weight;
        g_tree -= terms.back().weight.cwiseProduct(terms.back().residual);
      }
      const Eigen::Vector3d w_inv = w_sum.unaryExpr([](double w) { return w > 0 ? 1 / w : 0.0; });
      for (size_t a = 0; a < terms.size(); ++a) {
        const int fa = observations_[rows[a]].frame;
        const Term& ta = terms[a];
        const Eigen::Matrix<double, 4, 3> jw = ta.jacobian.transpose() * ta.weight.asDiagonal();
        gradient.segment<4>(4 * fa) += jw * (ta.residual + g_tree.cwiseProduct(w_inv));
        system_->Block(system_->Slot(fa, fa)) += jw * ta.jacobian;
        for (size_t b = 0; b < terms.size(); ++b) {
          const int fb = observations_[rows[b]].frame;
          if (fb < fa) continue;
          const Term& tb = terms[b];
          system_->Block(*slot++) -= jw * w_inv.cwiseProduct(tb.weight).asDiagonal() * tb.jacobian;
        }
      }
    }
    for (size_t e = 0; e < edges_.size(); ++e) {
      const PoseGraphEdge& edge = edges_[e];
      const LinearizedEdge lin = LinearizeEdge(poses_[edge.from], poses_[edge.to], edge);
      const bool forward = edge.from < edge.to;
      const Eigen::Matrix4d& jf = forward ? lin.jacobian_from : lin.jacobian_to;
      const Eigen::Matrix4d& jt = forward ? lin.jacobian_to : lin.jacobian_from;
      const int from = std::min(edge.from, edge.to), to = std::max(edge.from, edge.to);
      gradient.segment<4>(4 * from) += jf.transpose() * lin.residual;
      gradient.segment<4>(4 * to) += jt.transpose() * lin.residual;
      system_->Block(edge_slots_[e][0]) += jf.transpose() * jf;
      system_->Block(edge_slots_[e][1]) += jt.transpose() * jt;
      system_->Block(edge_slots_[e][2]) += jf.transpose() * jt;
    }
    return gradient;
  }

  // Solves the damped reduced system and moves the poses.
  bool Step(const Eigen::VectorXd& gradient, double lambda) {
    Eigen::VectorXd step;
    if (!system_->Solve(-gradient, lambda, step)) return false;
    for (size_t i = 0; i < poses_.size(); ++i) {
      poses_[i].translation += step.segment<3>(4 * i);
      poses_[i].yaw = WrapAngle(poses_[i].yaw + step(4 * i + 3));
    }
    return true;
  }

  // Each tree: the (robust) weighted mean of its observations under the current poses.
  void UpdateTrees(const Kernel& kernel) {
    for (size_t j = 0; j < trees_.size(); ++j) {
      if (by_tree_[j].empty()) continue;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();
      for (int k : by_tree_[j]) {
        const Term t =
            Evaluate(poses_[observations_[k].frame], trees_[j], observations_[k], kernel, options_);
        sum += t.weight.cwiseProduct(t.residual + trees_[j]);
        w += t.weight;
      }
      if (w.x() > 0) trees_[j].head<2>() = sum.head<2>() / w.x();
      if (w.z() > 0) {
        trees_[j].z() = sum.z() / w.z();
      } else if (!std::isfinite(trees_[j].z())) {
        trees_[j].z() = FirstHeight(j);
      }
    }
  }

  // A start for a tree without a height: its first observation's, or NaN.
  double FirstHeight(size_t tree) const {
    for (int k : by_tree_[tree]) {
      const auto& o = observations_[k];
      const double z = o.level_position.z() + poses_[o.frame].translation.z();
      if (o.weight_z > 0 && std::isfinite(z)) return z;
    }
    return kUnknown;
  }

  double Cost(const Kernel& kernel) const {
    double cost = 0;
    for (size_t j = 0; j < trees_.size(); ++j) {
      for (int k : by_tree_[j]) {
        cost +=
            Evaluate(poses_[observations_[k].frame], trees_[j], observations_[k], kernel, options_)
                .cost;
      }
    }
    for (const PoseGraphEdge& edge : edges_) {
      cost += LinearizeEdge(poses_[edge.from], poses_[edge.to], edge).residual.squaredNorm();
    }
    return cost;
  }

  double Rms() const {
    double sum = 0, w = 0;
    for (const auto& o : observations_) {
      const Term t = Evaluate(poses_[o.frame], trees_[o.tree], o, Kernel{}, options_);
      sum += o.weight_xy * t.residual.head<2>().squaredNorm();
      w += o.weight_xy;
    }
    return w > 0 ? std::sqrt(sum / w) : 0;
  }

  const TreeAdjustmentOptions& options_;
  const std::vector<TreeAdjustmentObservation>& observations_;
  const std::vector<PoseGraphEdge>& edges_;
  std::vector<Pose4> poses_;
  std::vector<Eigen::Vector3d> trees_;
  std::vector<std::vector<int>> by_tree_;
  std::unique_ptr<BlockSystem> system_;
  std::vector<int> slots_;                      // per tree, per observation pair (a, b >= a)
  std::vector<std::array<int, 3>> edge_slots_;  // per edge: (from, from), (to, to), (from, to)
};

}  // namespace

TreeAdjustmentResult AdjustTrees(std::vector<Pose4> poses, std::vector<Eigen::Vector3d> trees,
                                 const std::vector<TreeAdjustmentObservation>& observations,
                                 const std::vector<PoseGraphEdge>& edges,
                                 const TreeAdjustmentOptions& options) {
  options.Check();
  Adjuster adjuster(std::move(poses), std::move(trees), observations, edges, options);
  return adjuster.Run();
}

std::vector<double> SmoothHeights(const std::vector<double>& apparent, double step_sigma,
                                  double outlier_scale, int iterations) {
  if (!(step_sigma > 0) || !(outlier_scale > 0)) {
    throw std::invalid_argument("SmoothHeights: step_sigma and outlier_scale must be > 0 m");
  }
  const int n = static_cast<int>(apparent.size());
  std::vector<double> z(n, 0.0);
  // Start: the median of the known apparent heights within 10 frames.
  for (int i = 0; i < n; ++i) {
    std::vector<double> window;
    for (int k = std::max(0, i - 10); k <= std::min(n - 1, i + 10); ++k) {
      if (std::isfinite(apparent[k])) window.push_back(apparent[k]);
    }
    if (window.empty()) continue;
    std::nth_element(window.begin(), window.begin() + window.size() / 2, window.end());
    z[i] = window[window.size() / 2];
  }
  // Tridiagonal normal equations (Thomas algorithm), reweighted.
  const double k = 1 / (step_sigma * step_sigma);
  std::vector<double> diag(n), rhs(n), upper(n);
  for (int iteration = 0; iteration < iterations && n > 1; ++iteration) {
    for (int i = 0; i < n; ++i) {
      double w = 0;
      if (std::isfinite(apparent[i])) {
        const double r = (z[i] - apparent[i]) / outlier_scale;
        w = 1 / (1 + r * r) / (outlier_scale * outlier_scale);
      }
      diag[i] = w + k * ((i > 0) + (i < n - 1)) + 1e-12;
      rhs[i] = w * (std::isfinite(apparent[i]) ? apparent[i] : 0.0);
      upper[i] = -k;
    }
    for (int i = 1; i < n; ++i) {  // forward elimination
      const double m = upper[i - 1] / diag[i - 1];
      diag[i] -= m * upper[i - 1];
      rhs[i] -= m * rhs[i - 1];
    }
    z[n - 1] = rhs[n - 1] / diag[n - 1];
    for (int i = n - 2; i >= 0; --i) z[i] = (rhs[i] - upper[i] * z[i + 1]) / diag[i];
  }
  return z;
}

}  // namespace forestmap::algorithms
