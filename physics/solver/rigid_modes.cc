// The rigid modes EquilibriumSolver holds: lateral translations and
// rotations about the axes through the reference vertex mean, orthonormal
// (build_rigid_modes), the norm of a vector's held part (held_component)
// and the projection onto their null space (project).
#include <Eigen/Dense>
#include <cmath>

#include "physics/solver/equilibrium.h"

namespace cellflow::solver {

void EquilibriumSolver::build_rigid_modes(const double* y) {
  rigid_modes_.clear();
  const std::size_t nv = body_->num_vertices;
  const Eigen::Index n = static_cast<Eigen::Index>(3 * nv);
  if (options_.hold_lateral_translation) {
    for (int axis = 0; axis < 2; ++axis) {
      Eigen::VectorXd mode = Eigen::VectorXd::Zero(n);
      for (std::size_t v = 0; v < nv; ++v) mode[static_cast<Eigen::Index>(3 * v + axis)] = 1.0;
      rigid_modes_.push_back(mode.normalized());
    }
  }
  // infinitesimal rotations about the axes through the vertex mean c of the
  // reference: e_a x (X - c)
  double centre[3] = {0.0, 0.0, 0.0};
  for (std::size_t v = 0; v < nv; ++v) {
    for (int a = 0; a < 3; ++a) centre[a] += y[3 * v + a];
  }
  for (double& c : centre) c /= static_cast<double>(nv);
  auto add_rotation = [&](int axis) {
    Eigen::VectorXd mode = Eigen::VectorXd::Zero(n);
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    for (std::size_t v = 0; v < nv; ++v) {
      // (e_axis x d)_a1 = -d_a2, (e_axis x d)_a2 = d_a1
      mode[static_cast<Eigen::Index>(3 * v + a1)] = -(y[3 * v + a2] - centre[a2]);
      mode[static_cast<Eigen::Index>(3 * v + a2)] = y[3 * v + a1] - centre[a1];
    }
    for (const Eigen::VectorXd& q : rigid_modes_) mode -= q * q.dot(mode);  // Gram-Schmidt
    const double norm = mode.norm();
    if (norm > 0.0) rigid_modes_.push_back(mode / norm);
  };
  if (options_.hold_spin_about_z) add_rotation(2);
  if (options_.hold_rolling) {
    add_rotation(0);
    add_rotation(1);
  }
}

double EquilibriumSolver::held_component(const Eigen::VectorXd& v) const {
  double sum = 0.0;
  for (const Eigen::VectorXd& q : rigid_modes_) sum += q.dot(v) * q.dot(v);
  return std::sqrt(sum);
}

void EquilibriumSolver::project(Eigen::VectorXd& v) const {
  for (const Eigen::VectorXd& q : rigid_modes_) v -= q * q.dot(v);
}

}  // namespace cellflow::solver
