// Static equilibrium solver on a small compressed sphere: the residual reaches
// the tolerance and is small by an independent evaluation, the plate reactions
// balance, Newton converges quadratically near the solution, an inverted
// initial state and an unsplittable load step end in kNumericalFailure, and
// two threads reach the equilibrium of one.
#include "physics/solver/equilibrium.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <span>
#include <string>

#include "physics/mesh/sphere_mesh.h"
#include "physics/solver/load_path.h"

namespace cellflow::solver {
namespace {

constexpr double kRadius = 8.6e-6;
constexpr double kYoungs = 150.0;

struct Problem {
  mesh::TetMesh mesh;
  elastic::ElasticBody body;
  std::vector<std::int32_t> surface;
  contact::PenaltyParams penalty;
  double z_top = 0.0, z_bottom = 0.0;

  contact::Obstacles plates(double travel_m) const {
    contact::Obstacles o;
    o.penalty = penalty;
    o.lower_plate_z_m = z_bottom - penalty.range_m;
    o.upper_plate_z_m = z_top + penalty.range_m - travel_m;
    return o;
  }
};

Problem make_problem(int vertices, double w) {
  Problem p;
  mesh::SphereMeshOptions options;
  options.radius_m = kRadius;
  options.target_vertex_count = vertices;
  p.mesh = mesh::make_sphere_mesh(options).value();
  const std::array<elastic::Material, 2> materials{elastic::Material{kYoungs, 0.48, w},
                                                   elastic::Material{kYoungs, 0.48, w}};
  p.body = elastic::make_elastic_body(p.mesh, materials).value();
  for (std::size_t v = 0; v < p.mesh.num_vertices(); ++v) {
    if (p.mesh.on_surface[v]) p.surface.push_back(static_cast<std::int32_t>(v));
    p.z_top = std::max(p.z_top, p.mesh.positions_m[3 * v + 2]);
    p.z_bottom = std::min(p.z_bottom, p.mesh.positions_m[3 * v + 2]);
  }
  p.penalty = contact::default_penalty(kYoungs, kRadius, mesh::mesh_quality(p.mesh).mean_edge_length_m);
  return p;
}

EquilibriumOptions options(double tolerance) {
  EquilibriumOptions o;
  o.residual_tolerance = tolerance;
  o.force_scale_n = kYoungs * kRadius * kRadius;
  o.threads = 1;
  return o;
}

// Equilibrium at 10 % compression reached through the load path.
std::vector<double> compressed_state(const Problem& p, EquilibriumSolver& solver, double deformation) {
  LoadPath path(
      solver, [&](double t) { return p.plates(t); }, p.mesh.positions_m, 0.0);
  for (int i = 1; i <= 4; ++i) {
    const LoadStepReport step = path.advance_to(2.0 * kRadius * deformation * i / 4, 5);
    EXPECT_TRUE(step.converged) << step.message;
  }
  return path.positions_m();
}

TEST(Equilibrium, ResidualBelowToleranceAndPlatesBalance) {
  const Problem p = make_problem(300, 1.0);
  EquilibriumSolver solver(p.body, p.surface, p.mesh.positions_m, options(1e-8));
  std::vector<double> y = compressed_state(p, solver, 0.1);
  const contact::Obstacles plates = p.plates(0.2 * kRadius);
  const EquilibriumReport report = solver.solve(plates, y);
  ASSERT_TRUE(report.converged) << report.message;
  EXPECT_LE(report.residual, 1e-8);
  // independent evaluation of the out-of-balance forces at the returned state
  std::vector<double> forces;
  EXPECT_LE(solver.residual(plates, y.data(), &forces), 1e-8);
  // every vertex: |f_v| <= ||f|| <= 1e-8 E R^2
  double max_vertex = 0.0;
  for (std::size_t v = 0; v < forces.size() / 3; ++v) {
    max_vertex = std::max(max_vertex, std::hypot(forces[3 * v], forces[3 * v + 1], forces[3 * v + 2]));
  }
  EXPECT_LE(max_vertex, 1e-8 * kYoungs * kRadius * kRadius);
  // the two plates carry the same force (within the residual)
  const double upper = report.contact.upper_plate_reaction_n, lower = report.contact.lower_plate_reaction_n;
  EXPECT_GT(upper, 0.0);
  EXPECT_NEAR(upper, -lower, 1e-8 * kYoungs * kRadius * kRadius);
  // Holding the rolling modes leaves the contact forces a net torque about x
  // and y (the elastic forces have none): the plate forces' lines of action
  // are offset by tau / F. Measured 0.017 R on this 300-vertex mesh.
  std::vector<double> contact_forces(y.size(), 0.0);
  contact::add_contact_forces(plates, p.surface, y.data(), contact_forces.data());
  double centre[3] = {0, 0, 0};
  const std::size_t nv = y.size() / 3;
  for (std::size_t v = 0; v < nv; ++v) {
    for (int a = 0; a < 3; ++a) centre[a] += y[3 * v + a] / static_cast<double>(nv);
  }
  double torque[3] = {0, 0, 0};
  for (std::size_t v = 0; v < nv; ++v) {
    const double d[3] = {y[3 * v] - centre[0], y[3 * v + 1] - centre[1], y[3 * v + 2] - centre[2]};
    const double* f = contact_forces.data() + 3 * v;
    torque[0] += d[1] * f[2] - d[2] * f[1];
    torque[1] += d[2] * f[0] - d[0] * f[2];
    torque[2] += d[0] * f[1] - d[1] * f[0];
  }
  const double offset = std::hypot(torque[0], torque[1]) / upper;
  std::printf("line-of-action offset of the plate forces: %.4f R\n", offset / kRadius);
  EXPECT_LT(offset, 0.05 * kRadius);
  EXPECT_GT(report.held_mode_residual, 0.0);
}

TEST(Equilibrium, NewtonConvergesQuadraticallyNearTheSolution) {
  const Problem p = make_problem(300, 0.5);
  EquilibriumOptions o = options(1e-12);
  o.max_forcing_term = 1e-12;  // exact Newton: the inner solve is not the limit
  o.max_cg_iterations = 20000;
  EquilibriumSolver solver(p.body, p.surface, p.mesh.positions_m, o);
  std::vector<double> y = compressed_state(p, solver, 0.1);
  // perturb the equilibrium by 0.02 % of R per coordinate
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-2e-4 * kRadius, 2e-4 * kRadius);
  for (double& c : y) c += noise(rng);
  const EquilibriumReport report = solver.solve(p.plates(0.2 * kRadius), y);
  ASSERT_TRUE(report.converged) << report.message;
  const std::vector<double>& r = report.residual_history;
  ASSERT_GE(r.size(), 3u);
  EXPECT_GT(r[0], 1e-3);  // the perturbation is felt
  // from there to 1e-12 in a handful of iterations
  EXPECT_LE(report.newton_iterations, 5);
  // quadratic: r_{k+1} <= C r_k^2 with C = 100 (measured C ~ 25-60) while
  // r_{k+1} is above the tolerance: below it the step is that of a linear
  // solve stopped at half the tolerance in force (the last iteration's
  // absolute CG stop, measured 4.7e-13 after 4.3e-9), and the rounding floor
  // is ~1e-14; linear convergence would leave r_{k+1} ~ r_k / 10
  int checked = 0;
  for (std::size_t k = 0; k + 1 < r.size(); ++k) {
    if (r[k] < 1e-2 && r[k + 1] > 1e-12) {
      EXPECT_LE(r[k + 1], 100.0 * r[k] * r[k]) << "iteration " << k << ": " << r[k] << " -> " << r[k + 1];
      ++checked;
    }
  }
  EXPECT_GE(checked, 2);
}

// A lagged elastic tangent (kept while Newton contracts the residual by 0.3
// per iteration, also from one load step to the next) reaches the
// equilibrium of the fresh tangent, to the solve's tolerance, with fewer
// assemblies than Newton iterations.
TEST(Equilibrium, LaggedTangentReachesTheEquilibriumOfTheFreshOne) {
  const Problem p = make_problem(300, 0.5);
  std::vector<std::vector<double>> states;
  std::vector<double> reactions;
  int lagged_assemblies = 0, lagged_iterations = 0;
  for (const double contraction : {0.0, 0.3}) {
    EquilibriumOptions o = options(1e-9);
    o.lagged_tangent_contraction = contraction;
    EquilibriumSolver solver(p.body, p.surface, p.mesh.positions_m, o);
    LoadPath path(
        solver, [&](double t) { return p.plates(t); }, p.mesh.positions_m, 0.0);
    int assemblies = 0, iterations = 0;
    double reaction = 0.0;
    for (int i = 1; i <= 6; ++i) {
      const LoadStepReport step = path.advance_to(2.0 * kRadius * 0.2 * i / 6, 5);
      ASSERT_TRUE(step.converged) << "contraction " << contraction << ": " << step.message;
      assemblies += step.last.tangent_assemblies;
      iterations += step.last.newton_iterations;
      if (contraction == 0.0) {
        EXPECT_EQ(step.last.tangent_assemblies, step.last.newton_iterations);
      }
      reaction = step.last.contact.upper_plate_reaction_n;
    }
    if (contraction > 0.0) {
      lagged_assemblies = assemblies;
      lagged_iterations = iterations;
    }
    states.push_back(path.positions_m());
    reactions.push_back(reaction);
  }
  std::printf("lagged tangent: %d assemblies for %d Newton iterations\n", lagged_assemblies,
              lagged_iterations);
  EXPECT_LT(lagged_assemblies, lagged_iterations);
  double largest = 0.0;
  for (std::size_t i = 0; i < states[0].size(); ++i)
    largest = std::max(largest, std::abs(states[0][i] - states[1][i]));
  EXPECT_LT(largest, 1e-6 * kRadius);
  EXPECT_GT(reactions[0], 0.0);
  EXPECT_NEAR(reactions[1], reactions[0], 1e-6 * reactions[0]);
}

// The linear solves of a mesh above ~2000 vertices run as one parallel
// region (physics/solver/pcg.cc); two threads must reach the equilibrium one
// thread reaches, to the solve's tolerance (the sums are split differently,
// so the Newton paths differ by round-off).
TEST(Equilibrium, TwoThreadsReachTheEquilibriumOfOne) {
  const Problem p = make_problem(2500, 0.5);
  ASSERT_GT(p.mesh.num_vertices(), 2000u);  // above the size of a one-thread solve
  std::vector<std::vector<double>> states;
  std::vector<double> reactions;
  for (const int threads : {1, 2}) {
    EquilibriumOptions o = options(1e-9);
    o.threads = threads;
    EquilibriumSolver solver(p.body, p.surface, p.mesh.positions_m, o);
    std::vector<double> y = p.mesh.positions_m;
    const EquilibriumReport report = solver.solve(p.plates(0.05 * kRadius), y);
    ASSERT_TRUE(report.converged) << threads << " threads: " << report.message;
    EXPECT_GT(report.cg_iterations, 10);
    states.push_back(y);
    reactions.push_back(report.contact.upper_plate_reaction_n);
  }
  double largest = 0.0;
  for (std::size_t i = 0; i < states[0].size(); ++i)
    largest = std::max(largest, std::abs(states[0][i] - states[1][i]));
  EXPECT_LT(largest, 1e-6 * kRadius);
  EXPECT_GT(reactions[0], 0.0);
  EXPECT_NEAR(reactions[1], reactions[0], 1e-6 * reactions[0]);
}

// The stall rule of solve(): a residual within 10 x the tolerance that has
// not halved in 20 Newton iterations fails at once as stalled, instead of
// spending max_newton_iterations. The rounding floor of the residual makes
// such a solve without any contrivance: from a perturbed equilibrium, exact
// Newton first runs to a tolerance nobody can reach (never within 10 x of
// it, so no stall: it runs out of iterations and shows the floor), then the
// same solve with the tolerance at a quarter of the lowest residual of that
// run (measured: the floor is flat within 1.1-1.4e-14, so its band of
// 10 x the tolerance holds it and the tolerance is out of reach).
TEST(Equilibrium, NewtonAtTheRoundingFloorStopsAsStalled) {
  const Problem p = make_problem(300, 0.5);
  std::vector<double> start;
  {
    EquilibriumSolver solver(p.body, p.surface, p.mesh.positions_m, options(1e-8));
    start = compressed_state(p, solver, 0.1);
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> noise(-2e-4 * kRadius, 2e-4 * kRadius);
  for (double& c : start) c += noise(rng);
  const contact::Obstacles plates = p.plates(0.2 * kRadius);
  constexpr int kMaxIterations = 80;
  auto floor_options = [](double tolerance) {
    EquilibriumOptions o = options(tolerance);
    o.max_forcing_term = 1e-12;  // exact Newton: at the floor within a few iterations
    o.max_cg_iterations = 20000;
    o.max_newton_iterations = kMaxIterations;
    return o;
  };
  EquilibriumSolver unreachable(p.body, p.surface, p.mesh.positions_m, floor_options(1e-30));
  std::vector<double> y = start;
  const EquilibriumReport floor_run = unreachable.solve(plates, y);
  ASSERT_FALSE(floor_run.converged);
  // It runs out of iterations, or (depending on the round-off of the path:
  // measured with another vertex numbering, after 54 iterations at 1.12e-14)
  // its line search finds no decrease of the energy at the floor; never a
  // stall, whose band (10 x the tolerance) is out of reach.
  if (floor_run.cause == FailureCause::kLineSearch) {
    EXPECT_LT(floor_run.residual, 1e-11) << floor_run.message;
  } else {
    EXPECT_EQ(floor_run.cause, FailureCause::kNotConverged);
    EXPECT_EQ(floor_run.newton_iterations, kMaxIterations) << floor_run.message;  // ran out
  }
  EXPECT_EQ(floor_run.message.find("stalled"), std::string::npos) << floor_run.message;
  EXPECT_GT(floor_run.residual_history.front(), 1e-3);  // the perturbation is felt
  const double lowest =
      *std::min_element(floor_run.residual_history.begin(), floor_run.residual_history.end());
  EXPECT_LT(lowest, 1e-11);  // a rounding floor, not a Newton that failed
  std::printf("rounding floor of the relative residual: %.3g\n", lowest);

  const double tolerance = 0.25 * lowest;
  EquilibriumSolver at_floor(p.body, p.surface, p.mesh.positions_m, floor_options(tolerance));
  y = start;
  const EquilibriumReport stalled = at_floor.solve(plates, y);
  ASSERT_FALSE(stalled.converged);
  EXPECT_EQ(stalled.cause, FailureCause::kNotConverged);
  EXPECT_NE(stalled.message.find("stalled"), std::string::npos) << stalled.message;
  EXPECT_LT(stalled.newton_iterations, kMaxIterations);
  std::printf("stalled after %d Newton iterations: %s\n", stalled.newton_iterations, stalled.message.c_str());
  // it fired within 10 x the tolerance, 20 iterations after the last halving
  const std::vector<double>& h = stalled.residual_history;
  EXPECT_LE(h.back(), 10.0 * tolerance);
  std::size_t last_halving = 0;
  double anchor = h[0];
  for (std::size_t k = 0; k < h.size(); ++k) {
    if (h[k] <= 0.5 * anchor) {
      anchor = h[k];
      last_halving = k;
    }
  }
  EXPECT_EQ(h.size() - 1 - last_halving, 20u);
}

TEST(Equilibrium, InvertedInitialStateIsANumericalFailure) {
  const Problem p = make_problem(300, 1.0);
  EquilibriumSolver solver(p.body, p.surface, p.mesh.positions_m, options(1e-6));
  std::vector<double> y = p.mesh.positions_m;
  // move vertex 0 of tet 7 through its opposite face
  const std::int32_t* tet = p.mesh.tets.data() + 4 * 7;
  double centroid[3] = {0, 0, 0};
  for (int a = 1; a < 4; ++a) {
    for (int c = 0; c < 3; ++c) centroid[c] += p.mesh.positions_m[3 * tet[a] + c] / 3.0;
  }
  for (int c = 0; c < 3; ++c) {
    y[3 * tet[0] + c] = 2.0 * centroid[c] - p.mesh.positions_m[3 * tet[0] + c];
  }
  const EquilibriumReport report = solver.solve(p.plates(0.0), y);
  EXPECT_FALSE(report.converged);
  EXPECT_EQ(report.cause, FailureCause::kInverted);
  EXPECT_GE(report.first_inverted_tet, 0);
  EXPECT_NE(report.message.find("inverted tetrahedron"), std::string::npos) << report.message;
}

TEST(LoadPath, StepThatCannotBeSplitFurtherFails) {
  const Problem p = make_problem(300, 1.0);
  EquilibriumOptions o = options(1e-6);
  o.max_newton_iterations = 1;  // no load step can converge in one iteration from rest
  EquilibriumSolver solver(p.body, p.surface, p.mesh.positions_m, o);
  LoadPath path(
      solver, [&](double t) { return p.plates(t); }, p.mesh.positions_m, 0.0);
  const LoadStepReport step = path.advance_to(0.4 * kRadius, 2);
  EXPECT_FALSE(step.converged);
  EXPECT_EQ(step.cause, FailureCause::kNotConverged);
  EXPECT_EQ(step.step_splits, 2);
  EXPECT_NE(step.message.find("after 2 step splits"), std::string::npos) << step.message;
  // the state stays at the last converged load
  EXPECT_EQ(path.load_m(), 0.0);
}

// A path from the equilibrium at 10 % compression whose solver has too few
// Newton iterations (5) for a jump from there to 40 %, so long steps halve.
struct StrictPathFromTenPercent {
  explicit StrictPathFromTenPercent(const Problem& p)
      : start(ten_percent_state(p)),
        strict(p.body, p.surface, p.mesh.positions_m, strict_options()),
        path(
            strict, [&p](double t) { return p.plates(t); }, start, 0.2 * kRadius) {}
  static std::vector<double> ten_percent_state(const Problem& p) {
    EquilibriumSolver generous(p.body, p.surface, p.mesh.positions_m, options(1e-6));
    return compressed_state(p, generous, 0.1);
  }
  static EquilibriumOptions strict_options() {
    EquilibriumOptions o = options(1e-6);
    o.max_newton_iterations = 5;
    return o;
  }
  const std::vector<double> start;
  EquilibriumSolver strict;
  LoadPath path;
};

// A converged sub-step that the state check refuses ends the load step at
// once: no further halving (a shorter step cannot make that state trusted),
// the state stays at the last accepted load, and the message is the check's.
TEST(LoadPath, RejectedSubStepEndsTheStepWithoutMoreSplits) {
  const Problem p = make_problem(300, 1.0);
  StrictPathFromTenPercent strict_path(p);
  const std::vector<double>& start = strict_path.start;
  LoadPath& path = strict_path.path;
  std::vector<double> checked_loads;
  path.set_state_check([&](double load_m, std::span<const double> positions_m) -> std::string {
    EXPECT_EQ(positions_m.size(), start.size());
    checked_loads.push_back(load_m);
    return load_m > 0.45 * kRadius ? "refused at " + std::to_string(load_m / kRadius) + " R" : "";
  });
  const LoadStepReport step = path.advance_to(0.8 * kRadius, 8);
  EXPECT_FALSE(step.converged);
  EXPECT_TRUE(step.state_rejected);
  EXPECT_EQ(step.cause, FailureCause::kNone);
  // The halvings go on until a sub-step converges; those below 0.45 R are
  // accepted, and the first one above it, refused, is the last checked.
  ASSERT_GE(checked_loads.size(), 1u);
  for (std::size_t k = 0; k + 1 < checked_loads.size(); ++k) EXPECT_LE(checked_loads[k], 0.45 * kRadius);
  EXPECT_GT(checked_loads.back(), 0.45 * kRadius);
  EXPECT_EQ(step.message.rfind("refused at ", 0), 0u) << step.message;
  EXPECT_NE(step.message.find("step splits)"), std::string::npos) << step.message;
  // the state stays at the last accepted sub-step
  EXPECT_DOUBLE_EQ(path.load_m(),
                   checked_loads.size() > 1 ? checked_loads[checked_loads.size() - 2] : 0.2 * kRadius);
  EXPECT_LT(path.load_m(), checked_loads.back());
}

TEST(LoadPath, HalvedStepsReachTheTarget) {
  const Problem p = make_problem(300, 1.0);
  StrictPathFromTenPercent strict_path(p);
  LoadPath& path = strict_path.path;
  const LoadStepReport step = path.advance_to(0.8 * kRadius, 8);
  ASSERT_TRUE(step.converged) << step.message;
  EXPECT_GE(step.step_splits, 1);
  EXPECT_DOUBLE_EQ(path.load_m(), 0.8 * kRadius);
  EXPECT_LE(step.last.residual, 1e-6);
}

}  // namespace
}  // namespace cellflow::solver
