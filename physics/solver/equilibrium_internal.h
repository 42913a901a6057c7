// Internal to cellflow::solver, shared by the sources of EquilibriumSolver
// (equilibrium.cc, pcg.cc) and not part of the public API
// (physics/solver/equilibrium.h): the preconditioner state of the linear
// solves, incomplete Cholesky or block Jacobi.
#pragma once

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <vector>

#include "physics/solver/equilibrium.h"

namespace cellflow::solver {

struct EquilibriumSolver::Preconditioning {
  Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<int>> incomplete_cholesky;
  bool factor_valid = false;
  Eigen::SparseMatrix<double> shifted;  // K + shift diag K when factored with a shift
  std::vector<double> block_inverse;    // 9 per vertex (block Jacobi)
};

}  // namespace cellflow::solver
