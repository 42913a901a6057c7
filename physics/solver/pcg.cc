// The linear solves of EquilibriumSolver: the product with K + shift diag K
// in the 3x3 vertex-block layout (matvec), projected preconditioned CG with
// the Steihaug stop at negative curvature (solve_linear), and the
// preconditioner, incomplete Cholesky of the shifted K or block Jacobi
// (build_preconditioner).
#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "physics/solver/equilibrium.h"
#include "physics/solver/equilibrium_internal.h"

namespace cellflow::solver {

namespace {

// Below this many unknowns (~2000 vertices) one linear solve's team costs
// more in barriers than the second thread gives.
constexpr std::int64_t kMinParallelDofs = 6000;
// Moments of a vector that give its components along the held rigid modes
// (EquilibriumSolver::centred_reference_).
constexpr int kMoments = 12;
// Reduced values per thread and round: r.r, r.z and the moments of z, or
// the moments of q and p.q.
constexpr int kReductionSlots = 16;

int team_size(int threads) {
  return threads > 0 ? threads : omp_get_max_threads();
}

}  // namespace

void EquilibriumSolver::multiply_rows(const double* x, double* out, double shift, std::int64_t begin,
                                      std::int64_t end, double* volumetric_z) const {
  // K is symmetric and stored with both triangles, so column i is row i:
  // out_i = K(:, i) . x. With the 3x3 block layout (columns 3v, 3v+1, 3v+2
  // hold the same neighbour rows, three consecutive rows per neighbour) one
  // neighbour index and one load of x_w serve nine products, and with
  // volumetric_z the three of the gather z_v = C_v g_v . x (Eq. of the
  // nodal-averaged volumetric tangent G^T C G) as well.
  const Eigen::SparseMatrix<double>& k = tangent_.stiffness();
  const auto* outer = k.outerIndexPtr();
  const auto* inner = k.innerIndexPtr();
  const double* values = k.valuePtr();
  const double* diag = diagonal_.data();
  const bool blocked = !block_neighbour_offsets_.empty();
  if (!blocked) {
    for (std::int64_t i = 3 * begin; i < 3 * end; ++i) {
      double sum = shift * diag[i] * x[i];
      for (auto s = outer[i]; s < outer[i + 1]; ++s) sum += values[s] * x[inner[s]];
      out[i] = sum;
    }
    return;
  }
  auto rows = [&](auto with_gather) {
    constexpr bool kGather = decltype(with_gather)::value;
    const double* g_rows = kGather ? tangent_.volumetric_rows() : nullptr;
    const double* coefficients = kGather ? tangent_.volumetric_coefficients() : nullptr;
    for (std::int64_t v = begin; v < end; ++v) {
      const double* c0 = values + outer[3 * v];
      const double* c1 = values + outer[3 * v + 1];
      const double* c2 = values + outer[3 * v + 2];
      double s0 = 0.0, s1 = 0.0, s2 = 0.0, sg = 0.0;
      const std::int64_t first = block_neighbour_offsets_[v], count = block_neighbour_offsets_[v + 1] - first;
      const std::int32_t* neighbours = block_neighbours_.data() + first;
      const double* g = kGather ? g_rows + 3 * first : nullptr;
      for (std::int64_t b = 0; b < count; ++b) {
        const double* xw = x + 3 * static_cast<std::int64_t>(neighbours[b]);
        const double x0 = xw[0], x1 = xw[1], x2 = xw[2];
        s0 += c0[3 * b] * x0 + c0[3 * b + 1] * x1 + c0[3 * b + 2] * x2;
        s1 += c1[3 * b] * x0 + c1[3 * b + 1] * x1 + c1[3 * b + 2] * x2;
        s2 += c2[3 * b] * x0 + c2[3 * b + 1] * x1 + c2[3 * b + 2] * x2;
        if constexpr (kGather) sg += g[3 * b] * x0 + g[3 * b + 1] * x1 + g[3 * b + 2] * x2;
      }
      out[3 * v] = s0 + shift * diag[3 * v] * x[3 * v];
      out[3 * v + 1] = s1 + shift * diag[3 * v + 1] * x[3 * v + 1];
      out[3 * v + 2] = s2 + shift * diag[3 * v + 2] * x[3 * v + 2];
      if constexpr (kGather) volumetric_z[v] = coefficients[v] * sg;
    }
  };
  if (volumetric_z != nullptr && fused_volumetric_gather_) {
    rows(std::true_type{});
  } else {
    rows(std::false_type{});
    if (volumetric_z != nullptr) tangent_.volumetric_gather(x, begin, end, volumetric_z);
  }
}

std::int64_t EquilibriumSolver::split_vertex(int rank, int size) const {
  // Vertex ranges of equal work: the prefix sums of the 3x3 blocks of K and
  // the entries of G per vertex (the two passes of every product).
  if (rank <= 0) return 0;
  const std::int64_t nv = static_cast<std::int64_t>(body_->num_vertices);
  if (rank >= size) return nv;
  const double goal = static_cast<double>(work_prefix_.back()) * rank / size;
  return std::lower_bound(work_prefix_.begin(), work_prefix_.end(), goal) - work_prefix_.begin();
}

void EquilibriumSolver::build_thread_halos(int team) {
  // With the neighbour lists N(v) of K's block columns (the same lists as
  // G's rows and G^T's columns when the gather is fused), a thread's product
  // reads p on N(range), its scatter reads C G p on N(range), and the gather
  // of the latter outside the range reads p on N(N(range)).
  const std::int64_t nv = static_cast<std::int64_t>(body_->num_vertices);
  const bool volumetric = tangent_.has_volumetric_operator();
  thread_halos_.assign(static_cast<std::size_t>(team), ThreadHalo{});
  std::vector<int> mark(static_cast<std::size_t>(nv));
  for (int rank = 0; rank < team; ++rank) {
    const std::int64_t vb = split_vertex(rank, team), ve = split_vertex(rank + 1, team);
    ThreadHalo& halo = thread_halos_[static_cast<std::size_t>(rank)];
    std::fill(mark.begin(), mark.end(), 0);
    for (std::int64_t v = vb; v < ve; ++v) mark[v] = 1;
    auto add_neighbours = [&](std::int64_t v, std::vector<std::int32_t>& to) {
      for (std::int64_t k = block_neighbour_offsets_[v]; k < block_neighbour_offsets_[v + 1]; ++k) {
        const std::int32_t w = block_neighbours_[k];
        if (mark[w] == 0) {
          mark[w] = 2;
          to.push_back(w);
        }
      }
    };
    for (std::int64_t v = vb; v < ve; ++v) add_neighbours(v, halo.p_halo);
    if (volumetric) {
      halo.gather_halo = halo.p_halo;
      for (const std::int32_t a : halo.gather_halo) add_neighbours(a, halo.p_halo);
      std::sort(halo.gather_halo.begin(), halo.gather_halo.end());
    }
    std::sort(halo.p_halo.begin(), halo.p_halo.end());
    halo.p.assign(static_cast<std::size_t>(3 * nv), 0.0);
    halo.volumetric_z.assign(static_cast<std::size_t>(volumetric ? nv : 0), 0.0);
  }
}

int EquilibriumSolver::solve_linear(const Eigen::VectorXd& rhs, double relative_tolerance,
                                    double absolute_tolerance, double shift, Eigen::VectorXd& dx,
                                    bool& negative_curvature) {
  // Projected PCG for (K + shift diag K) dx = rhs. The whole solve is one
  // parallel region: each thread owns a vertex range of every vector and does
  // the products, the preconditioner, the projections and the updates there;
  // an iteration meets two barriers, the two reductions, where a region per
  // product woke the team twice and left the vector work on one thread: each
  // thread updates its own copy of p on its range and on the vertices around
  // it that its product reads (ThreadHalo), and does the volumetric gather
  // C G p also on the vertices its scatter reads, so no thread waits for
  // another's p or C G p (without the block layout, or with G's rows on
  // other lists than K's, p and C G p are shared: four barriers).
  // On a VM each barrier is a wake-up of tens of microseconds. The halo work
  // is what a thread reads of the other ranges: on a generated mesh (in the
  // locality order of mesh/vertex_order.h) split in two at 2967 vertices,
  // 610 / 760 vertices of p (two rings) and 320 / 380 of the gather; in
  // TetGen's scattered numbering it was nearly all of the other range. Every
  // thread computes the same numbers as the vertex's owner (same operands,
  // same order), so the iterates are those of the shared-vector solve.
  // The projections of q and z onto the null space of the held modes share
  // the reductions and the passes of the updates. The reductions add the
  // threads' partial sums in rank order: the result depends on the team
  // size, not on the timing.
  const bool incomplete_cholesky = options_.preconditioner == Preconditioner::kIncompleteCholesky;
  const std::int64_t nv = static_cast<std::int64_t>(body_->num_vertices);
  const std::int64_t n = 3 * nv;
  // The incomplete Cholesky triangular solves are sequential: one thread.
  const int team = n > kMinParallelDofs && !incomplete_cholesky ? team_size(options_.threads) : 1;
  negative_curvature = false;
  dx.setZero(n);
  r_ = rhs;
  z_.resize(n);
  p_.resize(n);
  q_.resize(n);
  const bool volumetric = tangent_.has_volumetric_operator();
  volumetric_scratch_.resize(static_cast<std::size_t>(volumetric ? nv : 0));
  reduction_slots_.assign(static_cast<std::size_t>(2 * team * kReductionSlots), 0.0);
  if (work_prefix_.size() != static_cast<std::size_t>(nv)) {
    work_prefix_.resize(static_cast<std::size_t>(nv));
    std::int64_t sum = 0;
    for (std::int64_t v = 0; v < nv; ++v) {
      const std::int64_t blocks = block_neighbour_offsets_.empty()
                                      ? (tangent_.stiffness().outerIndexPtr()[3 * v + 1] -
                                         tangent_.stiffness().outerIndexPtr()[3 * v]) /
                                            3
                                      : block_neighbour_offsets_[v + 1] - block_neighbour_offsets_[v];
      sum += 1 + blocks + tangent_.volumetric_row_length(static_cast<std::size_t>(v));
      work_prefix_[v] = sum;
    }
  }
  // The held modes in closed form (see centred_reference_): 12 moments per
  // reduction instead of one component per mode, and the reference positions
  // instead of the mode vectors in every pass.
  const bool held = !rigid_modes_.empty();
  const int num_moments = held ? kMoments : 0;
  const double* centred = centred_reference_.data();
  const Preconditioning& pc = *preconditioning_;
  const bool private_halos =
      team > 1 && !block_neighbour_offsets_.empty() && (!volumetric || fused_volumetric_gather_);
  if (!private_halos) {
    thread_halos_.clear();
  } else if (thread_halos_.size() != static_cast<std::size_t>(team)) {
    build_thread_halos(team);
  }
  int iterations = 0;
  bool curvature_failed = false;

  auto run = [&](int rank, int size) {
    const std::int64_t vb = split_vertex(rank, size), ve = split_vertex(rank + 1, size);
    const std::int64_t b = 3 * vb, e = 3 * ve;  // this thread's unknowns
    double* r = r_.data();
    double* z = z_.data();
    double* q = q_.data();
    double* x = dx.data();
    ThreadHalo* halo = private_halos ? &thread_halos_[static_cast<std::size_t>(rank)] : nullptr;
    double* p = halo != nullptr ? halo->p.data() : p_.data();
    double* zv = halo != nullptr ? halo->volumetric_z.data() : volumetric_scratch_.data();
    int round = 0;
    // Adds every thread's values[0 .. count) in rank order (same total on
    // every thread); alternating slot sets make one barrier enough.
    auto reduce = [&](double* values, int count) {
      double* slots =
          reduction_slots_.data() + static_cast<std::size_t>((round & 1) * size * kReductionSlots);
      std::copy(values, values + count, slots + rank * kReductionSlots);
      ++round;
#pragma omp barrier
      for (int c = 0; c < count; ++c) {
        double total = 0.0;
        for (int t = 0; t < size; ++t) total += slots[t * kReductionSlots + c];
        values[c] = total;
      }
    };
    // mu[0 .. 12) = the moments of v on the range (sum_w v_w, then
    // sum_w v_w (X_w - c)^T row-major), if modes are held; returns u . v.
    auto moments = [&](const double* u, const double* v, double* mu) {
      double uv = 0.0;
      if (!held) {
#pragma omp simd reduction(+ : uv)
        for (std::int64_t k = b; k < e; ++k) uv += u[k] * v[k];
        return uv;
      }
      double s0 = 0.0, s1 = 0.0, s2 = 0.0;
      double m00 = 0.0, m01 = 0.0, m02 = 0.0, m10 = 0.0, m11 = 0.0, m12 = 0.0, m20 = 0.0, m21 = 0.0,
             m22 = 0.0;
      for (std::int64_t w = vb; w < ve; ++w) {
        const double v0 = v[3 * w], v1 = v[3 * w + 1], v2 = v[3 * w + 2];
        const double d0 = centred[3 * w], d1 = centred[3 * w + 1], d2 = centred[3 * w + 2];
        uv += u[3 * w] * v0 + u[3 * w + 1] * v1 + u[3 * w + 2] * v2;
        s0 += v0;
        s1 += v1;
        s2 += v2;
        m00 += v0 * d0;
        m01 += v0 * d1;
        m02 += v0 * d2;
        m10 += v1 * d0;
        m11 += v1 * d1;
        m12 += v1 * d2;
        m20 += v2 * d0;
        m21 += v2 * d1;
        m22 += v2 * d2;
      }
      const double all[kMoments] = {s0, s1, s2, m00, m01, m02, m10, m11, m12, m20, m21, m22};
      std::copy(all, all + kMoments, mu);
      return uv;
    };
    // The rigid field (t, A) of the held part sum_j m_j (m_j . v) = H mu(v).
    struct HeldField {
      double c[kMoments];
    };
    auto held_field = [&](const double* mu) {
      HeldField h = {};
      if (!held) return h;
      for (int i = 0; i < kMoments; ++i) {
        double sum = 0.0;
        for (int j = 0; j < kMoments; ++j) sum += held_projector_[kMoments * i + j] * mu[j];
        h.c[i] = sum;
      }
      return h;
    };
    // component a of the held field at vertex w: t_a + A_a. (X_w - c)
    auto held_part = [&](const HeldField& h, std::int64_t w, int a) {
      const double* d = centred + 3 * w;
      return h.c[a] + h.c[3 + 3 * a] * d[0] + h.c[4 + 3 * a] * d[1] + h.c[5 + 3 * a] * d[2];
    };
    // z = M^-1 r on the range (block Jacobi; incomplete Cholesky runs on a
    // team of one, over everything); then red = {r.r, r.z, mu(z)}.
    auto precondition = [&](double* red) {
      if (incomplete_cholesky) {
        const Eigen::VectorXd solved = pc.incomplete_cholesky.solve(r_);
        std::copy(solved.data(), solved.data() + n, z);
      } else {
        for (std::int64_t v = vb; v < ve; ++v) {
          const double* m = pc.block_inverse.data() + 9 * v;
          const double* rv = r + 3 * v;
          double* o = z + 3 * v;
          for (int a = 0; a < 3; ++a) o[a] = m[3 * a] * rv[0] + m[3 * a + 1] * rv[1] + m[3 * a + 2] * rv[2];
        }
      }
      double rr = 0.0;
#pragma omp simd reduction(+ : rr)
      for (std::int64_t k = b; k < e; ++k) rr += r[k] * r[k];
      red[0] = rr;
      red[1] = moments(r, z, red + 2);
      reduce(red, 2 + num_moments);
    };
    // v -= Q Q^T v on the range, from the moments of v
    auto remove_modes = [&](double* v, const double* mu) {
      if (!held) return;
      const HeldField h = held_field(mu);
      for (std::int64_t w = vb; w < ve; ++w) {
        for (int a = 0; a < 3; ++a) v[3 * w + a] -= held_part(h, w, a);
      }
    };
    double red[kReductionSlots] = {};

    // r = P rhs, target from its norm
    moments(r, r, red);
    reduce(red, num_moments);
    remove_modes(r, red);
    // z = P M^-1 r, p = z. Since r, p and every later r are in the null space
    // of Q^T (to round-off), r.(P z) = r.z and p.(P q) = p.q.
    precondition(red);
    const double target = std::max(relative_tolerance * std::sqrt(red[0]), absolute_tolerance);
    if (std::sqrt(red[0]) <= target) return;
    // p = P z + beta p on the range and, with private halos, around it
    // (z is complete after the reduction; p there is this thread's own).
    auto update_direction = [&](const HeldField& zh, double beta, bool first) {
      auto vertex = [&](std::int64_t w) {
        for (int a = 0; a < 3; ++a) {
          const std::int64_t k = 3 * w + a;
          p[k] = first ? z[k] - held_part(zh, w, a) : (z[k] - held_part(zh, w, a)) + beta * p[k];
        }
      };
      for (std::int64_t w = vb; w < ve; ++w) vertex(w);
      if (halo != nullptr) {
        for (const std::int32_t w : halo->p_halo) vertex(w);
      }
    };
    double rz = red[1];
    update_direction(held_field(red + 2), 0.0, true);
    for (int it = 0; it < options_.max_cg_iterations; ++it) {
      if (halo == nullptr) {
#pragma omp barrier
      }
      // q = (K + shift diag K) p
      multiply_rows(p, q, shift, vb, ve, volumetric ? zv : nullptr);
      if (volumetric) {
        if (halo != nullptr) {
          for (const std::int32_t a : halo->gather_halo) tangent_.volumetric_gather(p, a, a + 1, zv);
        } else {
#pragma omp barrier
        }
        tangent_.add_volumetric_scatter(zv, vb, ve, q);
      }
      // mu(q) and p.q
      red[kMoments] = moments(p, q, red);
      reduce(red, kMoments + 1);
      const double curvature = red[kMoments];
      if (!(curvature > 0.0)) {
        // Steihaug: stop at the last iterate; with none yet, the preconditioned
        // residual is a descent direction for the line search to scale.
        if (rank == 0) {
          curvature_failed = true;
          iterations = it + 1;
        }
        if (it == 0) std::copy(p + b, p + e, x + b);  // p = P z
        return;
      }
      const double alpha = rz / curvature;
      const HeldField qh = held_field(red);
      for (std::int64_t w = vb; w < ve; ++w) {
        for (int a = 0; a < 3; ++a) {
          const std::int64_t k = 3 * w + a;
          x[k] += alpha * p[k];
          r[k] -= alpha * (q[k] - held_part(qh, w, a));  // r -= alpha P q
        }
      }
      precondition(red);
      if (std::sqrt(red[0]) <= target) {
        if (rank == 0) iterations = it + 1;
        return;
      }
      const double rz_next = red[1];
      update_direction(held_field(red + 2), rz_next / rz, false);
      rz = rz_next;
    }
    if (rank == 0) iterations = options_.max_cg_iterations;
  };

  if (team == 1) {
    run(0, 1);
  } else {
#pragma omp parallel num_threads(team)
    run(omp_get_thread_num(), omp_get_num_threads());
  }
  negative_curvature = curvature_failed;
  return iterations;
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
  const std::int64_t nv = static_cast<std::int64_t>(body_->num_vertices);
  pc.block_inverse.resize(static_cast<std::size_t>(9 * nv));
  const double* values = tangent_.stiffness().valuePtr();
  const int team = 3 * nv > kMinParallelDofs ? team_size(options_.threads) : 1;
#pragma omp parallel for num_threads(team) schedule(static)
  for (std::int64_t v = 0; v < nv; ++v) {
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
