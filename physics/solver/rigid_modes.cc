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
  // The rigid-field coefficients phi = (t, A) of each mode, m(X) = t + A (X - c),
  // carried through the same Gram-Schmidt steps as the vectors.
  using Coefficients = Eigen::Matrix<double, 12, 1>;
  std::vector<Coefficients> coefficients;
  if (options_.hold_lateral_translation) {
    for (int axis = 0; axis < 2; ++axis) {
      Eigen::VectorXd mode = Eigen::VectorXd::Zero(n);
      for (std::size_t v = 0; v < nv; ++v) mode[static_cast<Eigen::Index>(3 * v + axis)] = 1.0;
      const double norm = mode.norm();
      rigid_modes_.push_back(mode / norm);
      Coefficients phi = Coefficients::Zero();
      phi[axis] = 1.0 / norm;
      coefficients.push_back(phi);
    }
  }
  // infinitesimal rotations about the axes through the vertex mean c of the
  // reference: e_a x (X - c)
  double centre[3] = {0.0, 0.0, 0.0};
  for (std::size_t v = 0; v < nv; ++v) {
    for (int a = 0; a < 3; ++a) centre[a] += y[3 * v + a];
  }
  for (double& c : centre) c /= static_cast<double>(nv);
  centred_reference_.resize(3 * nv);
  for (std::size_t v = 0; v < nv; ++v) {
    for (int a = 0; a < 3; ++a) centred_reference_[3 * v + a] = y[3 * v + a] - centre[a];
  }
  auto add_rotation = [&](int axis) {
    Eigen::VectorXd mode = Eigen::VectorXd::Zero(n);
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    for (std::size_t v = 0; v < nv; ++v) {
      // (e_axis x d)_a1 = -d_a2, (e_axis x d)_a2 = d_a1
      mode[static_cast<Eigen::Index>(3 * v + a1)] = -(y[3 * v + a2] - centre[a2]);
      mode[static_cast<Eigen::Index>(3 * v + a2)] = y[3 * v + a1] - centre[a1];
    }
    Coefficients phi = Coefficients::Zero();
    phi[3 + 3 * a1 + a2] = -1.0;
    phi[3 + 3 * a2 + a1] = 1.0;
    for (std::size_t j = 0; j < rigid_modes_.size(); ++j) {  // Gram-Schmidt
      const double component = rigid_modes_[j].dot(mode);
      mode -= rigid_modes_[j] * component;
      phi -= coefficients[j] * component;
    }
    const double norm = mode.norm();
    if (norm > 0.0) {
      rigid_modes_.push_back(mode / norm);
      coefficients.push_back(phi / norm);
    }
  };
  if (options_.hold_spin_about_z) add_rotation(2);
  if (options_.hold_rolling) {
    add_rotation(0);
    add_rotation(1);
  }
  Eigen::Matrix<double, 12, 12> projector = Eigen::Matrix<double, 12, 12>::Zero();
  for (const Coefficients& phi : coefficients) projector += phi * phi.transpose();
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 12; ++j) held_projector_[12 * i + j] = projector(i, j);
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
