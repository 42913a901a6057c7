// The linear solves of EquilibriumSolver: the product with K + shift diag K
// in the 3x3 vertex-block layout (matvec), projected preconditioned CG with
// the Steihaug stop at negative curvature (solve_linear), and the
// preconditioner, incomplete Cholesky of the shifted K or block Jacobi
// (build_preconditioner).
#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "physics/solver/equilibrium.h"
#include "physics/solver/equilibrium_internal.h"

namespace cellflow::solver {

namespace {

constexpr std::int64_t kMinParallelDofs = 6000;

int team_size(int threads) {
  return threads > 0 ? threads : omp_get_max_threads();
}

}  // namespace

void EquilibriumSolver::matvec(const Eigen::VectorXd& x, Eigen::VectorXd& out, double shift) const {
  // K is symmetric and stored with both triangles, so column i is row i:
  // out_i = K(:, i) . x. With the 3x3 block layout (columns 3v, 3v+1, 3v+2
  // hold the same neighbour rows, three consecutive rows per neighbour) one
  // neighbour index and one load of x_w serve nine products.
  const Eigen::SparseMatrix<double>& k = tangent_.stiffness();
  const auto* outer = k.outerIndexPtr();
  const auto* inner = k.innerIndexPtr();
  const double* values = k.valuePtr();
  const std::int64_t n = k.cols();
  const double* xs = x.data();
  double* os = out.data();
  const double* diag = diagonal_.data();
  const bool blocked = !block_neighbour_offsets_.empty();
  auto vertices = [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t v = begin; v < end; ++v) {
      if (!blocked) {
        for (std::int64_t i = 3 * v; i < 3 * v + 3; ++i) {
          double sum = shift * diag[i] * xs[i];
          for (auto s = outer[i]; s < outer[i + 1]; ++s) sum += values[s] * xs[inner[s]];
          os[i] = sum;
        }
        continue;
      }
      const double* c0 = values + outer[3 * v];
      const double* c1 = values + outer[3 * v + 1];
      const double* c2 = values + outer[3 * v + 2];
      double s0 = 0.0, s1 = 0.0, s2 = 0.0;
      const std::int64_t first = block_neighbour_offsets_[v], count = block_neighbour_offsets_[v + 1] - first;
      const std::int32_t* neighbours = block_neighbours_.data() + first;
      for (std::int64_t b = 0; b < count; ++b) {
        const double* xw = xs + 3 * static_cast<std::int64_t>(neighbours[b]);
        const double x0 = xw[0], x1 = xw[1], x2 = xw[2];
        s0 += c0[3 * b] * x0 + c0[3 * b + 1] * x1 + c0[3 * b + 2] * x2;
        s1 += c1[3 * b] * x0 + c1[3 * b + 1] * x1 + c1[3 * b + 2] * x2;
        s2 += c2[3 * b] * x0 + c2[3 * b + 1] * x1 + c2[3 * b + 2] * x2;
      }
      os[3 * v] = s0 + shift * diag[3 * v] * xs[3 * v];
      os[3 * v + 1] = s1 + shift * diag[3 * v + 1] * xs[3 * v + 1];
      os[3 * v + 2] = s2 + shift * diag[3 * v + 2] * xs[3 * v + 2];
    }
  };
  const std::int64_t nv = n / 3;
  // Below ~2000 vertices a fork/join costs more than the product; outside a
  // parallel region no OpenMP thread is woken at all.
  const int team = n > kMinParallelDofs ? team_size(options_.threads) : 1;
  if (team == 1) {
    vertices(0, nv);
  } else {
#pragma omp parallel num_threads(team)
    {
      const std::int64_t rank = omp_get_thread_num(), size = omp_get_num_threads();
      vertices(nv * rank / size, nv * (rank + 1) / size);
    }
  }
  // the applied part of K (nodal-averaged volumetric term); its diagonal is
  // in diag, so the shift above already covers it
  tangent_.add_volumetric_product(xs, os);
}

int EquilibriumSolver::solve_linear(const Eigen::VectorXd& rhs, double relative_tolerance,
                                    double absolute_tolerance, double shift, Eigen::VectorXd& dx,
                                    bool& negative_curvature) {
  Preconditioning& pc = *preconditioning_;
  const std::size_t nv = body_->num_vertices;
  auto apply_preconditioner = [&](const Eigen::VectorXd& in, Eigen::VectorXd& out) {
    if (options_.preconditioner == Preconditioner::kIncompleteCholesky) {
      out = pc.incomplete_cholesky.solve(in);
    } else {
      for (std::size_t v = 0; v < nv; ++v) {
        const double* b = pc.block_inverse.data() + 9 * v;
        const double* r = in.data() + 3 * v;
        double* o = out.data() + 3 * v;
        for (int a = 0; a < 3; ++a) o[a] = b[3 * a] * r[0] + b[3 * a + 1] * r[1] + b[3 * a + 2] * r[2];
      }
    }
    project(out);
  };

  negative_curvature = false;
  dx.setZero(rhs.size());
  r_ = rhs;
  project(r_);
  const double target = std::max(relative_tolerance * r_.norm(), absolute_tolerance);
  if (r_.norm() <= target) return 0;
  apply_preconditioner(r_, z_);
  p_ = z_;
  double rz = r_.dot(z_);
  int it = 0;
  for (; it < options_.max_cg_iterations; ++it) {
    matvec(p_, q_, shift);
    project(q_);
    const double curvature = p_.dot(q_);
    if (!(curvature > 0.0)) {
      // Steihaug: stop at the last iterate; with none yet, the preconditioned
      // residual is a descent direction for the line search to scale.
      negative_curvature = true;
      if (it == 0) dx = z_;
      return it + 1;
    }
    const double alpha = rz / curvature;
    dx += alpha * p_;
    r_ -= alpha * q_;
    if (r_.norm() <= target) return it + 1;
    apply_preconditioner(r_, z_);
    const double rz_next = r_.dot(z_);
    p_ = z_ + (rz_next / rz) * p_;
    rz = rz_next;
  }
  return it;
}

void EquilibriumSolver::build_preconditioner(double shift) {
  Preconditioning& pc = *preconditioning_;
  if (options_.preconditioner == Preconditioner::kIncompleteCholesky) {
    if (shift > 0.0 || !volumetric_blocks_.empty()) {
      // factor K + shift diag K: the matrix CG sees, except that of the
      // applied volumetric part only the diagonal blocks are in the pattern
      pc.shifted = tangent_.stiffness();
      double* values = pc.shifted.valuePtr();
      for (std::size_t v = 0; v < volumetric_blocks_.size() / 9; ++v) {
        for (int e = 0; e < 9; ++e) values[vertex_block_slot_[9 * v + e]] += volumetric_blocks_[9 * v + e];
      }
      for (std::size_t i = 0; i < diagonal_slot_.size(); ++i) {
        values[diagonal_slot_[i]] += shift * diagonal_[static_cast<Eigen::Index>(i)];
      }
      pc.incomplete_cholesky.compute(pc.shifted);
    } else {
      pc.incomplete_cholesky.compute(tangent_.stiffness());
    }
    pc.factor_valid = pc.incomplete_cholesky.info() == Eigen::Success;
    return;
  }
  const std::size_t nv = body_->num_vertices;
  pc.block_inverse.resize(9 * nv);
  const double* values = tangent_.stiffness().valuePtr();
  for (std::size_t v = 0; v < nv; ++v) {
    Eigen::Matrix3d block;
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) block(a, b) = values[vertex_block_slot_[9 * v + 3 * a + b]];
    }
    if (!volumetric_blocks_.empty()) {
      block += Eigen::Map<const Eigen::Matrix3d>(volumetric_blocks_.data() + 9 * v);
    }
    block.diagonal() *= (1.0 + shift);
    Eigen::Matrix3d inverse = block.inverse();
    if (!inverse.allFinite()) {
      inverse = Eigen::Matrix3d::Identity() / std::max(block.diagonal().maxCoeff(), 1e-300);
    }
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) pc.block_inverse[9 * v + 3 * a + b] = inverse(a, b);
    }
  }
  pc.factor_valid = true;
}

}  // namespace cellflow::solver
