#include "algorithms/mapping/pose_graph.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {

Pose4 Between(const Pose4& a, const Pose4& b) {
  const double c = std::cos(a.yaw), s = std::sin(a.yaw);
  const Eigen::Vector3d d = b.translation - a.translation;
  Pose4 out;
  out.translation = Eigen::Vector3d(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  out.yaw = WrapAngle(b.yaw - a.yaw);
  return out;
}

Pose4 Compose(const Pose4& a, const Pose4& relative) {
  const double c = std::cos(a.yaw), s = std::sin(a.yaw);
  const Eigen::Vector3d& r = relative.translation;
  Pose4 out;
  out.translation =
      a.translation + Eigen::Vector3d(c * r.x() - s * r.y(), s * r.x() + c * r.y(), r.z());
  out.yaw = WrapAngle(a.yaw + relative.yaw);
  return out;
}

void PoseGraphOptions::Check() const {
  if (max_iterations < 1)
    throw std::invalid_argument("PoseGraphOptions.max_iterations must be >= 1");
  if (!(tolerance >= 0)) throw std::invalid_argument("PoseGraphOptions.tolerance must be >= 0");
  if (!(huber > 0)) throw std::invalid_argument("PoseGraphOptions.huber must be > 0");
}

LinearizedEdge LinearizeEdge(const Pose4& a, const Pose4& b, const PoseGraphEdge& edge) {
  const Pose4 predicted = Between(a, b);
  LinearizedEdge out;
  out.residual.head<3>() = predicted.translation - edge.measurement.translation;
  out.residual(3) = WrapAngle(predicted.yaw - edge.measurement.yaw);
  const double c = std::cos(a.yaw), s = std::sin(a.yaw);
  Eigen::Matrix4d jb = Eigen::Matrix4d::Zero();
  jb << c, s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  Eigen::Matrix4d ja = -jb;
  ja(0, 3) = predicted.translation.y();  // d(R^T d)/d yaw_a = (r_y, -r_x)
  ja(1, 3) = -predicted.translation.x();
  const Eigen::Vector4d inv_sigma = edge.sigma.cwiseInverse();
  out.residual = out.residual.cwiseProduct(inv_sigma);
  out.jacobian_from = inv_sigma.asDiagonal() * ja;
  out.jacobian_to = inv_sigma.asDiagonal() * jb;
  return out;
}

namespace {

double HuberWeight(double norm, double threshold) {
  return norm <= threshold ? 1.0 : threshold / norm;
}

double Cost(const std::vector<Pose4>& poses, const std::vector<PoseGraphEdge>& edges,
            double huber) {
  double cost = 0;
  for (const PoseGraphEdge& edge : edges) {
    const double r = LinearizeEdge(poses[edge.from], poses[edge.to], edge).residual.norm();
    cost += edge.robust && r > huber ? huber * (2 * r - huber) : r * r;
  }
  return cost;
}

}  // namespace

PoseGraphResult OptimizePoseGraph(std::vector<Pose4> initial,
                                  const std::vector<PoseGraphEdge>& edges, int fixed_node,
                                  const PoseGraphOptions& options) {
  options.Check();
  const int n = static_cast<int>(initial.size());
  for (const PoseGraphEdge& edge : edges) {
    if (edge.from < 0 || edge.from >= n || edge.to < 0 || edge.to >= n || edge.from == edge.to) {
      throw std::invalid_argument("pose graph edge " + std::to_string(edge.from) + " -> " +
                                  std::to_string(edge.to) + " names no pair of the " +
                                  std::to_string(n) + " nodes");
    }
    if (!(edge.sigma.minCoeff() > 0)) {
      throw std::invalid_argument("pose graph edge sigma must be > 0");
    }
  }
  PoseGraphResult result;
  result.poses = std::move(initial);
  result.initial_cost = result.final_cost = Cost(result.poses, edges, options.huber);
  if (n < 2 || edges.empty()) return result;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::VectorXd gradient = Eigen::VectorXd::Zero(4 * n);
    for (const PoseGraphEdge& edge : edges) {
      const LinearizedEdge lin =
          LinearizeEdge(result.poses[edge.from], result.poses[edge.to], edge);
      const double w = edge.robust ? HuberWeight(lin.residual.norm(), options.huber) : 1.0;
      const int index[2] = {4 * edge.from, 4 * edge.to};
      const Eigen::Matrix4d* jac[2] = {&lin.jacobian_from, &lin.jacobian_to};
      for (int p = 0; p < 2; ++p) {
        gradient.segment<4>(index[p]) += w * jac[p]->transpose() * lin.residual;
        for (int q = 0; q < 2; ++q) {
          const Eigen::Matrix4d block = w * jac[p]->transpose() * *jac[q];
          for (int r = 0; r < 4; ++r) {
            for (int c = 0; c < 4; ++c)
              triplets.emplace_back(index[p] + r, index[q] + c, block(r, c));
          }
        }
      }
    }
    for (int k = 0; k < 4; ++k) triplets.emplace_back(4 * fixed_node + k, 4 * fixed_node + k, 1e12);
    Eigen::SparseMatrix<double> hessian(4 * n, 4 * n);
    hessian.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(hessian);
    if (solver.info() != Eigen::Success) break;
    const Eigen::VectorXd step = solver.solve(-gradient);
    for (int i = 0; i < n; ++i) {
      result.poses[i].translation += step.segment<3>(4 * i);
      result.poses[i].yaw = WrapAngle(result.poses[i].yaw + step(4 * i + 3));
    }
    result.iterations = iteration + 1;
    const double cost = Cost(result.poses, edges, options.huber);
    const double previous = result.final_cost;
    result.final_cost = cost;
    if (previous - cost <= options.tolerance * std::max(previous, 1e-12)) break;
  }
  return result;
}

}  // namespace forestmap::algorithms
