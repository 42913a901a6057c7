// EquilibriumSolver: set-up of the slots and the block structure of the
// tangent K, the total potential, forces and projected residual with
// contact, the tangent with the contact Hessian, the contact step limit, and
// the Newton loop of solve(): Eisenstat-Walker forcing, Levenberg-Marquardt
// damping and the line search. The linear solves are in pcg.cc, the held
// rigid modes in rigid_modes.cc.
#include "physics/solver/equilibrium.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <type_traits>

#include "physics/solver/equilibrium_internal.h"

namespace cellflow::solver {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Armijo sufficient-decrease constant of the line search.
constexpr double kArmijo = 1e-4;
// Relative size of Pi's rounding noise: below it a change of Pi says nothing
// and the line search judges the trial by its residual instead.
constexpr double kEnergyRoundoff = 1e-11;
// Smallest Levenberg-Marquardt damping (relative to diag K); below it, none.
constexpr double kMinDamping = 1e-6;
// First damping after CG met negative curvature.
constexpr double kNegativeCurvatureDamping = 1e-3;
// Solves per Newton iteration (each with more damping) before giving up.
constexpr int kMaxAttempts = 10;

// Newton iterations of one solve after which the linear solves are made
// accurate (forcing term at most kHardStateForcing), see solve().
constexpr int kSlowNewtonIterations = 2;
constexpr double kHardStateForcing = 1e-2;
// Below this many vertices the tangent is assembled on one thread whatever
// the team: the assembly meets a barrier per tet colour (elastic::
// TangentAssembler), each a wake-up of tens of microseconds on a VM. In
// TetGen's scattered numbering a 2967-vertex mesh had 220 colours (80k of a
// 2-thread run's 155k context switches on the curve); in the
// locality order of generated meshes (mesh/vertex_order.h) it has 15, and
// the 2-thread assembly pays: issue's curve 2 threads / 1 thread 0.70
// (median of 4 alternating rounds; 0.98 with the assembly on one thread),
// default compression spec 0.62 (median of 6). The same crossover as the
// linear solve's (kMinParallelDofs, pcg.cc). Meshes read from a file keep
// their numbering, and may have many more colours.
constexpr std::size_t kMinParallelAssemblyVertices = 2000;
// Where a linear solve stops at the latest: this fraction of the residual
// tolerance (absolute, in force), see solve().
constexpr double kFinalLinearTolerance = 0.5;
// A solve that has come within kStallBand of the residual tolerance and has
// not halved its residual in kStallIterations Newton iterations has stalled
// (healthy Newton is quadratic there): it fails at once, so the load path
// halves the step instead of spending max_newton_iterations (200) on it at
// each of its splits. Measured (the stability matrix's indentation/modulus/E1:
// 2.5 um probe to 0.475 of the diameter, 1000 vertices; the residual hovers
// at 2-7e-6 against 1e-6): see docs/stability/README.md.
constexpr double kStallBand = 10.0;
constexpr int kStallIterations = 20;

std::string format_double(double value) {
  std::ostringstream out;
  out.precision(3);
  out << value;
  return out.str();
}

}  // namespace

EquilibriumSolver::EquilibriumSolver(const elastic::ElasticBody& body,
                                     std::vector<std::int32_t> contact_vertices,
                                     std::span<const double> reference_positions_m,
                                     EquilibriumOptions options, std::vector<std::int32_t> contact_triangles)
    : body_(&body),
      reference_positions_(reference_positions_m.begin(), reference_positions_m.end()),
      contact_vertices_(std::move(contact_vertices)),
      contact_triangles_(std::move(contact_triangles)),
      options_(options),
      tangent_(body),
      preconditioning_(std::make_unique<Preconditioning>()) {
  tangent_.set_threads(body.num_vertices < kMinParallelAssemblyVertices ? 1 : options_.threads);
  build_rigid_modes(reference_positions_.data());
  // Slots of the diagonal 3x3 blocks in K's values: column 3v+j holds the
  // rows of v's neighbours (v among them) in sorted order.
  const Eigen::SparseMatrix<double>& k = tangent_.stiffness();
  const auto* outer = k.outerIndexPtr();
  const auto* inner = k.innerIndexPtr();
  const std::size_t nv = body.num_vertices;
  diagonal_slot_.assign(3 * nv, -1);
  std::vector<std::int64_t>& block_slot = vertex_block_slot_;
  block_slot.assign(9 * nv, -1);
  for (std::size_t col = 0; col < 3 * nv; ++col) {
    const std::size_t v = col / 3;
    for (auto s = outer[col]; s < outer[col + 1]; ++s) {
      const std::size_t row = static_cast<std::size_t>(inner[s]);
      if (row / 3 == v) block_slot[9 * v + 3 * (row % 3) + col % 3] = s;
      if (row == col) diagonal_slot_[col] = s;
    }
  }
  contact_diagonal_slot_.resize(9 * contact_vertices_.size());
  for (std::size_t c = 0; c < contact_vertices_.size(); ++c) {
    for (int e = 0; e < 9; ++e) contact_diagonal_slot_[9 * c + e] = block_slot[9 * contact_vertices_[c] + e];
  }
  contact_blocks_.assign(9 * contact_vertices_.size(), 0.0);
  // Slots of the 9 vertex-pair blocks of each contact triangle: its edges are
  // tet edges, so K holds them (rows sorted within a column).
  auto slot_of = [&](std::size_t row, std::size_t col) -> std::int64_t {
    const auto* first = inner + outer[col];
    const auto* last = inner + outer[col + 1];
    const auto* it =
        std::lower_bound(first, last, static_cast<Eigen::SparseMatrix<double>::StorageIndex>(row));
    return it != last && static_cast<std::size_t>(*it) == row ? outer[col] + (it - first) : -1;
  };
  const std::size_t triangles = contact_triangles_.size() / 3;
  triangle_slots_.assign(81 * triangles, -1);
  for (std::size_t t = 0; t < triangles; ++t) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) {
            const std::size_t row = 3 * static_cast<std::size_t>(contact_triangles_[3 * t + i]) + a;
            const std::size_t col = 3 * static_cast<std::size_t>(contact_triangles_[3 * t + j]) + b;
            triangle_slots_[81 * t + 9 * (3 * i + j) + 3 * a + b] = slot_of(row, col);
          }
        }
      }
    }
  }
  triangle_blocks_.assign(81 * triangles, 0.0);
  // Vertex-block structure for the matrix-vector product, if K has it.
  bool blocked = true;
  block_neighbour_offsets_.assign(nv + 1, 0);
  for (std::size_t v = 0; v < nv && blocked; ++v) {
    const auto length = outer[3 * v + 1] - outer[3 * v];
    blocked = length % 3 == 0 && outer[3 * v + 2] - outer[3 * v + 1] == length &&
              outer[3 * v + 3] - outer[3 * v + 2] == length;
    for (auto e = 0; blocked && e < length; e += 3) {
      const auto row = inner[outer[3 * v] + e];
      for (int j = 0; j < 3 && blocked; ++j) {
        for (int i = 0; i < 3 && blocked; ++i)
          blocked = inner[outer[3 * v + j] + e + i] == row + i && row % 3 == 0;
      }
      if (blocked) block_neighbours_.push_back(static_cast<std::int32_t>(row / 3));
    }
    block_neighbour_offsets_[v + 1] = static_cast<std::int64_t>(block_neighbours_.size());
  }
  if (!blocked) {
    block_neighbours_.clear();
    block_neighbour_offsets_.clear();
  }
  if (blocked && tangent_.has_volumetric_operator()) {
    const auto offsets = tangent_.volumetric_patch_offsets();
    const auto patches = tangent_.volumetric_patches();
    fused_volumetric_gather_ =
        std::equal(offsets.begin(), offsets.end(), block_neighbour_offsets_.begin(),
                   block_neighbour_offsets_.end()) &&
        std::equal(patches.begin(), patches.end(), block_neighbours_.begin(), block_neighbours_.end());
  }
  const Eigen::Index n = static_cast<Eigen::Index>(3 * nv);
  diagonal_.setZero(n);
  r_.setZero(n);
  z_.setZero(n);
  p_.setZero(n);
  q_.setZero(n);
}

EquilibriumSolver::~EquilibriumSolver() = default;

bool EquilibriumSolver::evaluate_forces(const contact::Obstacles& obstacles, const double* y,
                                        Eigen::VectorXd& forces, double& energy,
                                        EquilibriumReport& report) const {
  forces.setZero(static_cast<Eigen::Index>(3 * body_->num_vertices));
  const elastic::ElasticEvaluation el =
      elastic::add_elastic_forces(*body_, y, forces.data(), options_.threads);
  if (el.first_inverted_tet >= 0) {
    report.first_inverted_tet = el.first_inverted_tet;
    energy = kInfinity;
    return false;
  }
  const contact::ContactEvaluation ct =
      contact::add_contact_forces(obstacles, contact_vertices_, y, forces.data());
  energy = el.energy_j + ct.energy_j;
  if (!std::isfinite(energy) || !forces.allFinite()) {
    energy = kInfinity;
    return false;
  }
  report.elastic_energy_j = el.energy_j;
  report.contact = ct;
  return true;
}

double EquilibriumSolver::total_energy(const contact::Obstacles& obstacles, const double* positions_m) const {
  const elastic::ElasticEvaluation el = elastic::elastic_energy(*body_, positions_m, options_.threads);
  if (el.first_inverted_tet >= 0) return kInfinity;
  const double pi = el.energy_j + contact::contact_energy(obstacles, contact_vertices_, positions_m).energy_j;
  return std::isfinite(pi) ? pi : kInfinity;
}

double EquilibriumSolver::residual(const contact::Obstacles& obstacles, const double* positions_m,
                                   std::vector<double>* forces_n) const {
  Eigen::VectorXd f;
  double energy;
  EquilibriumReport scratch;
  if (!evaluate_forces(obstacles, positions_m, f, energy, scratch)) return kInfinity;
  project(f);
  if (forces_n) forces_n->assign(f.data(), f.data() + f.size());
  return f.norm() / options_.force_scale_n;
}

void EquilibriumSolver::assemble_tangent(const contact::Obstacles& obstacles, const double* y,
                                         bool reuse_elastic) {
  double* values = tangent_.stiffness().valuePtr();
  const std::size_t entries = static_cast<std::size_t>(tangent_.stiffness().nonZeros());
  if (reuse_elastic && elastic_values_.size() == entries) {
    std::copy(elastic_values_.begin(), elastic_values_.end(), values);
  } else {
    tangent_.assemble(y);
    if (options_.lagged_tangent_contraction > 0.0) elastic_values_.assign(values, values + entries);
  }
  std::fill(contact_blocks_.begin(), contact_blocks_.end(), 0.0);
  // The positive semidefinite part of the probe Hessian: the dropped term is
  // a relative s / (2 Rp) of the curvature and keeps K positive definite.
  contact::add_contact_hessian_blocks(obstacles, contact_vertices_, y, contact_blocks_.data(),
                                      /*positive_semidefinite=*/true);
  for (std::size_t e = 0; e < contact_blocks_.size(); ++e) {
    if (contact_blocks_[e] != 0.0) values[contact_diagonal_slot_[e]] += contact_blocks_[e];
  }
  // The probe on the surface triangles: the exact Hessian of the closest-point
  // distance (the consistent tangent; measured against the positive
  // semidefinite part in the scene tests).
  if (obstacles.probe && !obstacles.probe_triangles.empty() &&
      obstacles.probe_triangles.size() == contact_triangles_.size()) {
    std::fill(triangle_blocks_.begin(), triangle_blocks_.end(), 0.0);
    contact::add_probe_triangle_hessian(obstacles, y, triangle_blocks_.data(),
                                        options_.positive_semidefinite_contact);
    for (std::size_t e = 0; e < triangle_blocks_.size(); ++e) {
      if (triangle_blocks_[e] != 0.0 && triangle_slots_[e] >= 0)
        values[triangle_slots_[e]] += triangle_blocks_[e];
    }
  }
  for (std::size_t i = 0; i < diagonal_slot_.size(); ++i) {
    diagonal_[static_cast<Eigen::Index>(i)] = values[diagonal_slot_[i]];
  }
  if (tangent_.has_volumetric_operator()) {
    volumetric_blocks_.assign(9 * body_->num_vertices, 0.0);
    tangent_.add_volumetric_diagonal_blocks(volumetric_blocks_.data());
    for (std::size_t v = 0; v < body_->num_vertices; ++v) {
      for (int i = 0; i < 3; ++i)
        diagonal_[static_cast<Eigen::Index>(3 * v + i)] += volumetric_blocks_[9 * v + 4 * i];
    }
  }
}

double EquilibriumSolver::contact_step_limit(const contact::Obstacles& obstacles, const double* y,
                                             const Eigen::VectorXd& dx) const {
  const std::size_t count = contact_vertices_.size();
  contact_gaps_.resize(count);
  contact_normals_.resize(3 * count);
  contact::nearest_obstacle(obstacles, contact_vertices_, y, contact_gaps_.data(), contact_normals_.data());
  const double range = obstacles.penalty.range_m;
  double limit = 1.0;
  for (std::size_t k = 0; k < count; ++k) {
    const double gap = contact_gaps_[k];
    // Inside an obstacle the law is linear (exact in the quadratic model);
    // no obstacle at all: infinite gap.
    if (!(gap > 0.0) || !std::isfinite(gap)) continue;
    const double* n = contact_normals_.data() + 3 * k;
    const double* d = dx.data() + 3 * static_cast<std::int64_t>(contact_vertices_[k]);
    const double approach = -(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]);  // gap decrease per unit step
    const double allowed = gap - (std::min(gap, range) - 0.5 * range);
    if (approach * limit > allowed) limit = allowed / approach;
  }
  if (obstacles.probe && !obstacles.probe_triangles.empty()) {
    const std::size_t triangles = obstacles.probe_triangles.size() / 3;
    triangle_gaps_.resize(triangles);
    triangle_normals_.resize(3 * triangles);
    triangle_barycentric_.resize(3 * triangles);
    contact::probe_triangle_gaps(obstacles, y, triangle_gaps_.data(), triangle_normals_.data(),
                                 triangle_barycentric_.data());
    for (std::size_t t = 0; t < triangles; ++t) {
      const double gap = triangle_gaps_[t];
      if (!(gap > 0.0)) continue;
      const double* n = triangle_normals_.data() + 3 * t;
      double approach = 0.0;  // of the closest point, moving with the barycentric weights
      for (int i = 0; i < 3; ++i) {
        const double* d = dx.data() + 3 * static_cast<std::int64_t>(obstacles.probe_triangles[3 * t + i]);
        approach -= triangle_barycentric_[3 * t + i] * (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]);
      }
      const double allowed = gap - (std::min(gap, range) - 0.5 * range);
      if (approach * limit > allowed) limit = allowed / approach;
    }
  }
  return limit;
}

EquilibriumReport EquilibriumSolver::solve(const contact::Obstacles& obstacles,
                                           std::span<double> positions_m) {
  EquilibriumReport report;
  const Eigen::Index n = static_cast<Eigen::Index>(3 * body_->num_vertices);
  Eigen::Map<Eigen::VectorXd> y(positions_m.data(), n);
  // The held modes are a linear constraint on the displacement from the
  // reference, Q^T (y - X) = 0; every correction lies in its null space, so
  // the equilibrium found is the unique constrained one, whatever the path.
  {
    Eigen::VectorXd displacement = y - Eigen::Map<const Eigen::VectorXd>(reference_positions_.data(), n);
    Eigen::VectorXd held = displacement;
    project(displacement);
    y -= held - displacement;
  }
  Eigen::VectorXd forces, trial_forces, dx, trial(n);
  double energy = 0.0;
  if (!evaluate_forces(obstacles, y.data(), forces, energy, report)) {
    report.cause = report.first_inverted_tet >= 0 ? FailureCause::kInverted : FailureCause::kNotFinite;
    report.message = report.first_inverted_tet >= 0
                         ? "initial state has inverted tetrahedron " +
                               std::to_string(report.first_inverted_tet) + " (J <= 0)"
                         : "initial state has a non-finite energy or force";
    report.residual = kInfinity;
    return report;
  }
  report.held_mode_residual = held_component(forces) / options_.force_scale_n;
  project(forces);
  double force_norm = forces.norm();
  double previous_force_norm = -1.0;
  double forcing = options_.max_forcing_term;
  const double scale = options_.force_scale_n;
  Preconditioning& pc = *preconditioning_;
  damping_ = 0.0;  // Newton first; the damping grows only where the model fails
  damping_growth_ = 2.0;

  double halving_anchor = kInfinity;  // the residual at the last halving, and its iteration
  int halving_iteration = 0;
  for (int iteration = 0;; ++iteration) {
    report.residual = force_norm / scale;
    report.residual_history.push_back(report.residual);
    if (report.residual <= options_.residual_tolerance) {
      report.converged = true;
      return report;
    }
    if (iteration == options_.max_newton_iterations) {
      report.cause = FailureCause::kNotConverged;
      report.message = "Newton did not converge in " + std::to_string(iteration) +
                       " iterations (relative residual " + format_double(report.residual) + ")";
      return report;
    }
    if (report.residual <= 0.5 * halving_anchor) {
      halving_anchor = report.residual;
      halving_iteration = iteration;
    }
    if (report.residual <= kStallBand * options_.residual_tolerance &&
        iteration - halving_iteration >= kStallIterations) {
      report.cause = FailureCause::kNotConverged;
      report.message = "Newton stalled at relative residual " + format_double(report.residual) + " (within " +
                       format_double(kStallBand) + " x the tolerance, not halved in " +
                       std::to_string(kStallIterations) + " iterations)";
      return report;
    }
    ++report.newton_iterations;
    // Lagged elastic tangent (options_.lagged_tangent_contraction): kept
    // while the last iteration contracted the residual enough and nothing
    // needed damping. Measured on the probe curves (40 points, 1 thread,
    // 2026-12-02; an assembly of the 4907-vertex mesh costs ~13 ms, 20 CG
    // iterations): colloidal probe 147 -> 36 assemblies, 5281 -> 5891 CG
    // iterations with contraction 0.3 (with the quadratic predictor of
    // load_path.h 39 and 5493; 0.15: 59 and 5282; 0.5: 32 and 5661); small
    // probe (5685 vertices) 123 -> 20 assemblies, 4569 -> 4633 CG. The forces
    // move by up to 0.1 % at the first points (1e-6 E R^2 is 2e-3 of the
    // small probe's first force), within what the residual tolerance leaves
    // there (1e-6 against 1e-8: up to 0.3 %).
    bool reuse_elastic = false;
    if (options_.lagged_tangent_contraction > 0.0 && !elastic_tangent_stale_ && damping_ == 0.0) {
      reuse_elastic =
          iteration == 0 || force_norm <= options_.lagged_tangent_contraction * previous_force_norm;
    }
    elastic_tangent_stale_ = false;
    if (!reuse_elastic) ++report.tangent_assemblies;
    assemble_tangent(obstacles, y.data(), reuse_elastic);

    // Eisenstat-Walker choice 2 with its safeguard against a sudden drop.
    if (previous_force_norm > 0.0) {
      const double ratio = force_norm / previous_force_norm;
      double next = 0.9 * ratio * ratio;
      if (0.9 * forcing * forcing > 0.1) next = std::max(next, 0.9 * forcing * forcing);
      forcing = std::min(options_.max_forcing_term, next);
    }
    // Past the first kSlowNewtonIterations of a solve the Newton system is
    // solved accurately: at large compression (stiff contact rows beside soft
    // rim modes) the truncated CG directions of a loose forcing term make
    // Newton cycle. Measured (w = 0.25, 3000 vertices, to 0.9 in 45 points):
    // the curve reaches 0.80 instead of 0.66 with a forcing term of 1e-2 or
    // 1e-3 from the third iteration on (0.68 from the sixth or ninth); the
    // issue's 40-point curve takes 8.7 s with 1e-2, 11.3 s with 1e-3.
    if (iteration >= kSlowNewtonIterations) forcing = std::min(forcing, kHardStateForcing);
    // No point in solving the linear system beyond half the target: near the
    // solution the step leaves ||f|| at about the CG residual plus C ||f||^2
    // (C ~ 60, tests/solver), far below the target once ||f|| < 1e-4. Measured
    // on the curve (2967 vertices, 40 points to 0.8, 1 thread):
    // 318 -> 324 Newton and 20362 -> 17672 CG iterations against a tenth
    // (a third: 318 and 18425), F(0.8) the same to 3e-8.
    const double absolute_tolerance = kFinalLinearTolerance * options_.residual_tolerance * scale;

    bool accepted = false;
    std::int64_t inverted_in_search = -1;
    for (int attempt = 0; attempt < kMaxAttempts && !accepted; ++attempt) {
      if (!pc.factor_valid) {
        build_preconditioner(damping_);
        ++report.preconditioner_builds;
      }
      bool negative_curvature = false;
      const int cg = solve_linear(forces, forcing, absolute_tolerance, damping_, dx, negative_curvature);
      report.cg_iterations += cg;
      if (options_.preconditioner == Preconditioner::kBlockJacobi || cg > options_.refactor_cg_iterations ||
          negative_curvature) {
        pc.factor_valid = false;  // rebuild at the next solve
      }
      // Negative curvature: K is indefinite here (a compressed rim, a state
      // far from equilibrium). A truncated CG direction makes little progress;
      // shift K + lambda diag K until it is positive definite and solve again.
      if (negative_curvature && attempt + 1 < kMaxAttempts) {
        damping_ = std::max(damping_growth_ * damping_, kNegativeCurvatureDamping);
        damping_growth_ *= 2.0;
        pc.factor_valid = false;
        continue;
      }
      // Pi(y + a dx) = Pi(y) - a f.dx + O(a^2): dx must point downhill. The
      // damped quadratic model predicts the decrease f.dx / 2 of a CG iterate.
      const double slope = -forces.dot(dx);
      if (!(slope < 0.0) || !dx.allFinite()) {
        damping_ = std::max(damping_growth_ * damping_, kNegativeCurvatureDamping);
        damping_growth_ *= 2.0;
        pc.factor_valid = false;
        continue;
      }
      // A vertex entering an obstacle's penalty range stiffens far beyond what
      // the tangent at its present gap predicts (zero outside the range), and
      // a full step then overshoots by orders of magnitude in energy. The
      // step is capped so that no vertex goes more than half a range deeper.
      const double step_limit = contact_step_limit(obstacles, y.data(), dx);
      double step = step_limit;
      // the quadratic model's decrease over a (1 - a/2) (-slope) at step a
      const double predicted_decrease = -slope * step * (1.0 - 0.5 * step);
      double ratio = 0.0;
      for (int ls = 0; ls < options_.max_line_search_steps; ++ls) {
        trial = y + step * dx;
        double trial_energy;
        EquilibriumReport trial_report;
        if (!evaluate_forces(obstacles, trial.data(), trial_forces, trial_energy, trial_report)) {
          if (trial_report.first_inverted_tet >= 0) inverted_in_search = trial_report.first_inverted_tet;
          step *= 0.25;
          continue;
        }
        if (ls == 0) ratio = (energy - trial_energy) / predicted_decrease;
        const bool decrease = trial_energy <= energy + kArmijo * step * slope;
        bool roundoff_regime = false;
        if (!decrease && trial_energy - energy <= kEnergyRoundoff * std::abs(energy)) {
          // Pi cannot resolve the change: accept if the projected residual drops.
          Eigen::VectorXd projected = trial_forces;
          project(projected);
          roundoff_regime = projected.norm() < force_norm;
          if (ls == 0 && roundoff_regime) ratio = 1.0;
        }
        if (decrease || roundoff_regime) {
          y = trial;
          energy = trial_energy;
          forces = trial_forces;
          report.elastic_energy_j = trial_report.elastic_energy_j;
          report.contact = trial_report.contact;
          accepted = true;
          break;
        }
        // minimiser of the quadratic through Pi(0), Pi'(0) and Pi(step), kept in [step/10, step/2]
        const double quadratic = -slope * step * step / (2.0 * (trial_energy - energy - slope * step));
        step = std::clamp(quadratic, 0.1 * step, 0.5 * step);
      }
      // Levenberg-Marquardt update of the damping from the gain ratio rho of
      // the full step (Nielsen 1999): on success lambda *= max(1/3, 1 -
      // (2 rho - 1)^3) and the growth factor resets to 2; on a cut step
      // lambda *= growth, growth *= 2. Soft modes whose energy is not
      // quadratic (a flattened cell's rim at large compression) make full
      // Newton steps overshoot; the damping settles just above their stiffness.
      if (accepted && step == step_limit && ratio > 0.0) {
        const double t = 2.0 * ratio - 1.0;
        damping_ *= std::max(1.0 / 3.0, 1.0 - t * t * t);
        if (damping_ < kMinDamping) damping_ = 0.0;
        damping_growth_ = 2.0;
      } else {
        damping_ = std::max(damping_ * damping_growth_, kMinDamping);
        damping_growth_ *= 2.0;
        if (!accepted) pc.factor_valid = false;
      }
    }
    // A damped or failed iteration: the next one (or the next solve) starts
    // from a fresh tangent.
    if (!accepted || damping_ > 0.0) elastic_tangent_stale_ = true;
    if (!accepted) {
      report.residual = force_norm / scale;
      if (inverted_in_search >= 0) {
        report.cause = FailureCause::kInverted;
        report.first_inverted_tet = inverted_in_search;
        report.message = "no admissible Newton step: every shorter trial still inverts tetrahedron " +
                         std::to_string(inverted_in_search) + " (J <= 0) or raises the energy";
      } else {
        report.cause = FailureCause::kLineSearch;
        report.message = "line search found no decrease of the energy (relative residual " +
                         format_double(report.residual) + ")";
      }
      return report;
    }
    report.held_mode_residual = held_component(forces) / options_.force_scale_n;
    project(forces);
    previous_force_norm = force_norm;
    force_norm = forces.norm();
  }
}

}  // namespace cellflow::solver
