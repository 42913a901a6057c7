// Static equilibrium of one load step: the deformed positions y that minimise
//   Pi(y) = E_elastic(y) + E_contact(y)
// with the rigid obstacles (plates, probe) prescribed.
//
// Newton's method with the analytic tangent (elastic TangentAssembler plus the
// contact Hessian blocks), solved inexactly by preconditioned conjugate
// gradients (Eisenstat-Walker forcing terms), globalised by a backtracking
// line search on Pi that rejects any trial with an inverted tetrahedron
// (J <= 0) or a non-finite energy. Negative curvature met inside CG truncates
// the solve (Steihaug); a direction the line search cannot use is retried
// with a Levenberg shift K + lambda diag(K).
//
// Rigid modes. Frictionless plates fix neither the translation in x and y nor
// the rotation about z: Pi is invariant under them and K is singular along
// them. They are held by the linear constraint Q^T (y - X) = 0, Q the
// orthonormal rigid modes of the reference X (translations, rotations about
// its vertex mean): the initial guess is projected onto it and every Newton
// correction is projected out of Q (projected PCG), so the vertex mean keeps
// its x-y position, the cell does not spin, and the constrained equilibrium is
// unique (the same whatever the Newton path). Projection rather than a small
// regularisation: it is exact (no bias, no tuning constant, no near-singular
// matrix for CG) and costs a few dot products per CG iteration.
// The rotations about x and y (rolling between the plates) are held the same
// way by default: for a sphere rolling is neutral, and in the tangent it is
// resisted only by the vertices already inside the contact range, so Newton
// proposed rotations of 0.1 rad and more that the line search then cut back
// (25-35 Newton iterations per load step instead of 4-6). Holding them is
// what the experiment does (the FluidFM aperture holds the cell); the net
// torque it leaves is reported as held_mode_residual.
// For a probe on a sphere the lateral translation is not neutral but unstable
// (frictionless contact cannot hold a sphere under a sphere); holding it
// models a cell that sits in place on the substrate.
//
// Convergence: the out-of-balance force vector f = -grad Pi (3 per vertex,
// newtons) with the held rigid modes projected out, measured as
//   residual = ||f||_2 / (E R^2)
// where E R^2 (`force_scale_n`) is the force scale of the cell (the Hertz
// force at deformation eps is (4/3) E* R^2 eps^1.5). The Euclidean norm over
// all vertices bounds every vertex's imbalance and the error of the reaction
// on each obstacle.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "physics/contact/rigid_contact.h"
#include "physics/core/status.h"
#include "physics/elastic/elastic_body.h"

namespace cellflow::solver {

enum class Preconditioner {
  kBlockJacobi,         // inverse 3x3 diagonal blocks of K, rebuilt every Newton iteration
  kIncompleteCholesky,  // Eigen IncompleteCholesky (AMD ordering), refreshed when CG slows down
};

struct EquilibriumOptions {
  double residual_tolerance = 1e-6;  // ||f||_2 / force_scale_n at convergence
  double force_scale_n = 1.0;        // E R^2
  int max_newton_iterations = 40;
  int max_cg_iterations = 2000;
  // Inexact Newton: CG stops at ||r|| <= eta ||f||, eta from Eisenstat-Walker
  // choice 2, eta_k = 0.9 (||f_k|| / ||f_{k-1}||)^2, capped by this.
  double max_forcing_term = 0.1;
  int max_line_search_steps = 30;
  // Block Jacobi: 2.5 s against 4.5 s with incomplete Cholesky for the first
  // half of the 3000-vertex curve (one thread): IC halves the CG iterations
  // but its triangular solves and factorisations cost more than that.
  Preconditioner preconditioner = Preconditioner::kBlockJacobi;
  // The incomplete Cholesky factor is kept across Newton iterations and load
  // steps until a CG solve needs more than this many iterations.
  int refactor_cg_iterations = 60;
  bool hold_lateral_translation = true;  // project out x and y translation
  bool hold_spin_about_z = true;         // project out the rotation about z
  bool hold_rolling = true;              // project out the rotations about x and y
  // Lagged elastic tangent: while Newton contracts the residual by at least
  // this factor per iteration, the next iteration keeps the elastic part of K
  // from the last assembly (also across solves, i.e. load steps) and
  // re-evaluates only the contact blocks; after a slower iteration, a damped
  // or failed one, K is assembled afresh. 0: assemble every iteration (exact
  // Newton). With the inexact solves (forcing 0.1, then 1e-2) one Newton
  // iteration gains about one digit whichever K, and an assembly costs about
  // 20 CG iterations (4907 vertices); see the .cc for the measurement.
  double lagged_tangent_contraction = 0.0;
  // Probe on triangles: drop the term phi' hess d of the contact Hessian
  // (Gauss-Newton tangent) instead of the exact one.
  bool positive_semidefinite_contact = false;
  int threads = 0;  // OpenMP threads; 0 = OpenMP default
};

enum class FailureCause { kNone, kNotConverged, kInverted, kNotFinite, kLineSearch };

struct EquilibriumReport {
  bool converged = false;
  FailureCause cause = FailureCause::kNone;
  std::string message;  // why it failed, empty when converged
  int newton_iterations = 0;
  int cg_iterations = 0;
  int preconditioner_builds = 0;
  int tangent_assemblies = 0;  // elastic assemblies of K (fewer than Newton iterations with a lagged tangent)
  double residual = 0.0;       // relative, at the returned positions
  std::vector<double> residual_history;  // relative residual before each Newton iteration and at the end
  // Norm of the out-of-balance force along the held modes (net lateral force
  // and net torques of the contact forces, which the elastic forces cannot
  // balance), / force_scale_n. Zero by symmetry for a perfect sphere; it
  // measures what holding the modes changes.
  double held_mode_residual = 0.0;
  double elastic_energy_j = 0.0;
  contact::ContactEvaluation contact;  // at the returned positions
  std::int64_t first_inverted_tet = -1;
};

// Owns the tangent assembler, the preconditioner and the work arrays of one
// body; reused across load steps. `body` must outlive the solver.
class EquilibriumSolver {
 public:
  // `reference_positions_m` (3 per vertex) define the held modes: rigid
  // translations and rotations about the reference's vertex mean.
  // `contact_triangles` (3 vertex indices each) are the surface triangles a
  // probe may act on (Obstacles::probe_triangles must then be these): their
  // vertex pairs get the contact Hessian blocks in K.
  EquilibriumSolver(const elastic::ElasticBody& body, std::vector<std::int32_t> contact_vertices,
                    std::span<const double> reference_positions_m, EquilibriumOptions options,
                    std::vector<std::int32_t> contact_triangles = {});
  ~EquilibriumSolver();
  EquilibriumSolver(const EquilibriumSolver&) = delete;
  EquilibriumSolver& operator=(const EquilibriumSolver&) = delete;

  // Newton from the initial guess in positions_m (3 per vertex), first
  // projected onto the held-mode constraint Q^T (y - X) = 0; on return it
  // holds the last accepted iterate (the equilibrium when converged).
  EquilibriumReport solve(const contact::Obstacles& obstacles, std::span<double> positions_m);

  // Pi at y, +infinity if a tetrahedron is inverted or the value is not finite.
  double total_energy(const contact::Obstacles& obstacles, const double* positions_m) const;

  // Out-of-balance forces -grad Pi at y (3 per vertex) and the relative
  // residual with the held rigid modes projected out.
  double residual(const contact::Obstacles& obstacles, const double* positions_m,
                  std::vector<double>* forces_n = nullptr) const;

  const EquilibriumOptions& options() const { return options_; }
  std::span<const std::int32_t> contact_vertices() const { return contact_vertices_; }
  std::span<const std::int32_t> contact_triangles() const { return contact_triangles_; }
  const elastic::ElasticBody& body() const { return *body_; }

 private:
  struct Preconditioning;

  // Forces (elastic + contact) and energy at y; returns false on inversion/NaN.
  bool evaluate_forces(const contact::Obstacles& obstacles, const double* y, Eigen::VectorXd& forces,
                       double& energy, EquilibriumReport& report) const;
  void build_rigid_modes(const double* y);
  void project(Eigen::VectorXd& v) const;
  // Largest step a <= 1 along dx after which no contact vertex (or probe
  // triangle's closest point) outside an obstacle (gap g > 0) is deeper in
  // the penalty range than half a range beyond where it is now:
  // g + a n.dx >= min(g, r) - r / 2.
  double contact_step_limit(const contact::Obstacles& obstacles, const double* y,
                            const Eigen::VectorXd& dx) const;
  double held_component(const Eigen::VectorXd& v) const;
  // The tangent at y; with reuse_elastic its elastic part is that of the
  // last assembly (only the contact blocks are evaluated at y).
  void assemble_tangent(const contact::Obstacles& obstacles, const double* y, bool reuse_elastic);
  // out = (K + shift diag K) x on the rows of vertices [begin, end), without
  // the applied volumetric part (reads x on their neighbours); with
  // volumetric_z (fused_volumetric_gather_ only) also the volumetric gather
  // z_a = C_a g_a . x of those vertices, in the same pass over x.
  void multiply_rows(const double* x, double* out, double shift, std::int64_t begin, std::int64_t end,
                     double* volumetric_z = nullptr) const;
  // First vertex of thread rank's range of the linear solve (equal work).
  std::int64_t split_vertex(int rank, int size) const;
  void build_preconditioner(double shift);
  // Projected PCG for (K + shift diag K) dx = rhs; returns CG iterations.
  int solve_linear(const Eigen::VectorXd& rhs, double relative_tolerance, double absolute_tolerance,
                   double shift, Eigen::VectorXd& dx, bool& negative_curvature);

  const elastic::ElasticBody* body_;
  std::vector<double> reference_positions_;
  std::vector<std::int32_t> contact_vertices_;
  std::vector<std::int32_t> contact_triangles_;
  std::vector<std::int64_t> triangle_slots_;  // 81 per contact triangle, into K's values (layout of
                                              // contact::add_probe_triangle_hessian)
  std::vector<double> triangle_blocks_;
  mutable std::vector<double> triangle_gaps_, triangle_normals_, triangle_barycentric_;
  EquilibriumOptions options_;
  elastic::TangentAssembler tangent_;
  std::vector<std::int64_t> contact_diagonal_slot_;  // 9 per contact vertex, into K's values
  std::vector<std::int64_t> diagonal_slot_;          // 3 per vertex, into K's values
  std::vector<std::int64_t> vertex_block_slot_;      // 9 per vertex: its diagonal 3x3 block, row-major
  std::vector<double> contact_blocks_;
  // K's values of the last elastic assembly (no contact blocks); empty before it.
  std::vector<double> elastic_values_;
  bool elastic_tangent_stale_ = true;  // the next iteration must assemble (lagged tangent)
  mutable std::vector<double> contact_gaps_, contact_normals_;  // contact_step_limit scratch
  // Diagonal 3x3 blocks of the applied volumetric part of K (nodal-averaged
  // volumetric term, elastic::TangentAssembler), 9 per vertex; empty without it.
  std::vector<double> volumetric_blocks_;
  std::vector<std::int32_t> block_neighbours_;         // neighbour vertex of each 3x3 block of a block column
  std::vector<std::int64_t> block_neighbour_offsets_;  // per vertex; empty if K lacks the block layout
  // The rows of G (applied volumetric part) run over the same neighbour lists
  // as K's block columns: multiply_rows can do the gather of G^T C G.
  bool fused_volumetric_gather_ = false;
  Eigen::VectorXd diagonal_;                  // diag K (Levenberg shift)
  std::vector<Eigen::VectorXd> rigid_modes_;  // orthonormal
  // The same modes in closed form for the CG loop, which would otherwise
  // stream 6 stored mode vectors four times per iteration: every held mode is
  // a rigid field m(X) = t + A (X - c), so m . v needs only the 12 moments
  // mu(v) = (sum_w v_w, sum_w v_w (X_w - c)^T) and the held part
  // sum_j m_j (m_j . v) is the rigid field of coefficients H mu(v), with
  // H = sum_j phi_j phi_j^T (phi_j = (t_j, A_j row-major)).
  std::vector<double> centred_reference_;  // X_w - c, 3 per vertex
  double held_projector_[144] = {};        // H, 12 x 12 row-major
  std::unique_ptr<Preconditioning> preconditioning_;
  double damping_ = 0.0;         // Levenberg-Marquardt lambda of the current solve
  double damping_growth_ = 2.0;  // its growth factor after a failed step
  // CG work vectors
  Eigen::VectorXd r_, z_, p_, q_;
  std::vector<double> volumetric_scratch_;  // C G p, one per vertex
  std::vector<double> reduction_slots_;     // per thread partial sums, two rounds
  std::vector<std::int64_t> work_prefix_;   // per vertex, prefix sum of its product work
  // A thread's own copy of the CG direction p on its vertex range and the
  // vertices around it that its products read, and of the volumetric
  // gather C G p on the vertices its scatter reads (solve_linear: with these
  // a team meets two barriers per CG iteration instead of four).
  struct ThreadHalo {
    std::vector<std::int32_t> p_halo;       // outside the range: p read by the product and gather
    std::vector<std::int32_t> gather_halo;  // outside the range: C G p read by the scatter
    std::vector<double> p;                  // 3 per vertex (only range + p_halo are used)
    std::vector<double> volumetric_z;       // 1 per vertex (only range + gather_halo are used)
  };
  void build_thread_halos(int team);
  std::vector<ThreadHalo> thread_halos_;  // one per thread of the last team; empty for one thread
};

}  // namespace cellflow::solver
