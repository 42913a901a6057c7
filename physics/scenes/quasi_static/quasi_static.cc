#include "physics/scenes/quasi_static/quasi_static.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <string>

#include "physics/cell/cell_body.h"
#include "physics/contact/rigid_contact.h"
#include "physics/contact/surface_triangles.h"
#include "physics/elastic/elastic_body.h"
#include "physics/mesh/quadratic_tets.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/observables/shape.h"
#include "physics/solver/equilibrium.h"
#include "physics/solver/load_path.h"

namespace cellflow::scenes {

namespace {

// Allowed ranges of the numerics (QuasiStaticNumerics in spec.proto).
constexpr double kMinResidualTolerance = 1e-12, kMaxResidualTolerance = 1e-2;
constexpr int kMaxNewtonIterations = 1000;
constexpr int kMaxStepSplits = 30;
// Load points: a curve of 10000 points is finer than any measured one, and
// the cost of a run grows as load points x vertices (each point one Newton
// solve over the mesh): at most kMaxLoadPointVertices, e.g. 40 points at
// 20000 vertices or 10000 at 4000, hours on one core, not days.
constexpr int kMaxLoadPoints = 10000;
constexpr double kMaxLoadPointVertices = 4e7;
constexpr int kMaxThreads = 1024;
// Largest compression / diameter and probe travel / radius a scene runs.
constexpr double kMaxDeformation = 0.9;
constexpr double kMaxIndentationRadii = 1.8;
// Smallest compression / diameter (and probe travel / diameter): below 1e-3
// the travel (2e-3 R) is inside the default contact layer (5e-3 R) and the
// penetration tolerance (1e-3 R): the curve would measure the penalty.
constexpr double kMinDeformation = 1e-3;
// Probe radius: 10 nm (an AFM tip) to 10 cm, and from a hundredth of the
// cell radius (narrower slips between the surface vertices of any mesh this
// code makes) to a hundred radii (wider is a plate).
constexpr double kMinProbeRadiusM = 1e-8, kMaxProbeRadiusM = 1e-1;
constexpr double kMinProbeRadii = 1e-2, kMaxProbeRadii = 1e2;
// Contact stiffness against the cell's force per length E R: the default
// (contact::default_penalty) lies at about 10-400 E R for 200-20000 vertices;
// a thousandth of that lets the plates pass through the cell, a thousand
// times more leaves the Newton tangent without the cell's digits.
constexpr double kMinContactStiffnessER = 1e-2, kMaxContactStiffnessER = 1e5;
// A contact range beyond a tenth of the radius would blur the first contact;
// below 1e-5 R every Newton step jumps across it (and a range-only spec
// scales the stiffness by default range / range: 1e-300 gave k = inf).
constexpr double kMaxContactRangeRadii = 0.1;
constexpr double kMinContactRangeRadii = 1e-5;
// Gap tolerance of the augmented Lagrangian: below 1e-8 R the gap is below
// the rounding of the positions' updates; above 1e-2 R it is the penalty's.
constexpr double kMinGapToleranceRadii = 1e-8, kMaxGapToleranceRadii = 1e-2;
// Smallest element volume ratio J a converged state (load point or sub-step)
// may reach. Converged curves to deformation 0.9 reach 0.50-0.56 (w = 1, nu
// 0.48-0.499); collapsing ones fall below 0.1 (bench/stability). With nu =
// 0.45 the continuum of eq. 5 itself passes it near 0.895 (CalculiX,
// validation/fe/README.md). Below it the state is not trusted.
constexpr double kMinVolumeRatio = 0.2;
// Pole spacing of the graded sphere (mesh::PoleGrading's range).
constexpr double kMinPoleSpacingRadii = 1e-3;
// The default indentation grading refines the poles by at most this factor
// below the uniform spacing (a curve of many load points would otherwise ask
// for a pole spacing of its first, tiny contact).
constexpr double kMaxDefaultPoleRefinement = 10.0;

// The reaction of a plate or probe on a hyperelastic cell grows with the
// travel. A converged point with less force than the one before (by more than
// this fraction; the residual tolerance is far below it) is a discretisation
// failure: a probe narrower than the mesh spacing slips between surface
// vertices (stress matrix: 2.5 um probe on 1000 vertices, -4 % at 0.25).
constexpr double kMaxForceDrop = 1e-3;

// "lie in [lo, hi]" for an integer range.
std::string int_range(int lo, int hi) {
  return "lie in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
}

// "[lo, hi]" and "lie in [lo, hi]" for a real range.
std::string interval(double lo, double hi) {
  // Appended, not "[" + ...: GCC 12 -O3 reports a false -Wrestrict on the
  // inlined operator+(const char*, string&&).
  std::string text = "[";
  text += number_text(lo);
  text += ", ";
  text += number_text(hi);
  text += "]";
  return text;
}
std::string real_range(double lo, double hi) {
  return "lie in " + interval(lo, hi);
}

Violations check_numerics(const QuasiStaticOptions& n, const cell::CellParams& cell) {
  const double radius_m = cell.radius_m;
  // E R: the cell's force per length (the contact stiffness scale)
  const double force_per_length = cell.material.youngs_modulus_pa * radius_m;
  Violations v;
  if (!(n.residual_tolerance >= kMinResidualTolerance && n.residual_tolerance <= kMaxResidualTolerance)) {
    v.add_value(
        "residual_tolerance", n.residual_tolerance,
        "lie in [" + number_text(kMinResidualTolerance) + ", " + number_text(kMaxResidualTolerance) + "]");
  }
  if (n.max_newton_iterations < 1 || n.max_newton_iterations > kMaxNewtonIterations) {
    v.add("max_newton_iterations",
          "= " + std::to_string(n.max_newton_iterations) + " must " + int_range(1, kMaxNewtonIterations));
  }
  if (n.max_step_splits < 0 || n.max_step_splits > kMaxStepSplits) {
    v.add("max_step_splits",
          "= " + std::to_string(n.max_step_splits) + " must " + int_range(0, kMaxStepSplits));
  }
  if (n.contact_stiffness_n_per_m &&
      !(*n.contact_stiffness_n_per_m > 0.0 && std::isfinite(*n.contact_stiffness_n_per_m))) {
    v.add_value("contact_stiffness_n_per_m", *n.contact_stiffness_n_per_m,
                "be > 0 and finite (or unset for the derived default)");
  } else if (n.contact_stiffness_n_per_m &&
             !(*n.contact_stiffness_n_per_m >= kMinContactStiffnessER * force_per_length &&
               *n.contact_stiffness_n_per_m <= kMaxContactStiffnessER * force_per_length)) {
    v.add_value(
        "contact_stiffness_n_per_m", *n.contact_stiffness_n_per_m,
        "lie in [" + number_text(kMinContactStiffnessER) + ", " + number_text(kMaxContactStiffnessER) +
            "] E R = " +
            interval(kMinContactStiffnessER * force_per_length, kMaxContactStiffnessER * force_per_length) +
            " (E = cell.material.youngs_modulus_pa, R = cell.radius_m; or unset for the default)");
  }
  if (n.contact_range_m &&
      !(*n.contact_range_m > 0.0 && *n.contact_range_m <= kMaxContactRangeRadii * radius_m)) {
    v.add_value("contact_range_m", *n.contact_range_m,
                "lie in (0, " + number_text(kMaxContactRangeRadii) + " radius_m] = (0, " +
                    number_text(kMaxContactRangeRadii * radius_m) + "] (or unset for the default)");
  } else if (n.contact_range_m && !(*n.contact_range_m >= kMinContactRangeRadii * radius_m)) {
    v.add_value(
        "contact_range_m", *n.contact_range_m,
        "lie in [" + number_text(kMinContactRangeRadii) + " radius_m, " + number_text(kMaxContactRangeRadii) +
            " radius_m] = " + real_range(kMinContactRangeRadii * radius_m, kMaxContactRangeRadii * radius_m) +
            " (or unset for the default)");
  }
  if (n.contact_gap_tolerance_m && !(*n.contact_gap_tolerance_m >= kMinGapToleranceRadii * radius_m &&
                                     *n.contact_gap_tolerance_m <= kMaxGapToleranceRadii * radius_m)) {
    v.add_value(
        "contact_gap_tolerance_m", *n.contact_gap_tolerance_m,
        "lie in [" + number_text(kMinGapToleranceRadii) + ", " + number_text(kMaxGapToleranceRadii) +
            "] radius_m = " + interval(kMinGapToleranceRadii * radius_m, kMaxGapToleranceRadii * radius_m) +
            " (or unset for the default)");
  }
  if (n.pole_spacing_m && *n.pole_spacing_m != 0.0 &&
      !(*n.pole_spacing_m >= kMinPoleSpacingRadii * radius_m && *n.pole_spacing_m <= radius_m)) {
    v.add_value("pole_spacing_m", *n.pole_spacing_m,
                "be 0 (uniform mesh) or lie in [" + number_text(kMinPoleSpacingRadii) +
                    ", 1] radius_m = " + number_text(kMinPoleSpacingRadii * radius_m) + " ... " +
                    number_text(radius_m) + " m (or unset for the default)");
  }
  if (!(n.pole_grading_growth >= 0.1 && n.pole_grading_growth <= 1.0)) {
    v.add_value("pole_grading_growth", n.pole_grading_growth, "lie in [0.1, 1]");
  }
  if (!(n.pole_ring_jitter >= 0.0 && n.pole_ring_jitter <= 1.0)) {
    v.add_value("pole_ring_jitter", n.pole_ring_jitter, "lie in [0, 1]");
  }
  if (n.threads < 0 || n.threads > kMaxThreads) {
    v.add("threads", "= " + std::to_string(n.threads) + " must " + int_range(0, kMaxThreads));
  }
  return v;
}

void check_load_points(int load_points, const cell::CellParams& cell, Violations& v) {
  if (load_points < 1 || load_points > kMaxLoadPoints) {
    v.add("load_points", "= " + std::to_string(load_points) + " must " + int_range(1, kMaxLoadPoints));
    return;
  }
  // The mesh's size is known here for a generated sphere; a mesh file's
  // vertices are counted when it is read (run_load_points).
  if (cell.mesh_file.empty() &&
      static_cast<double>(load_points) * cell.target_vertex_count > kMaxLoadPointVertices) {
    v.add("load_points", "= " + std::to_string(load_points) +
                             " with cell.target_vertex_count = " + std::to_string(cell.target_vertex_count) +
                             " must keep load_points x vertices at most " +
                             number_text(kMaxLoadPointVertices) + " (the run's cost)");
  }
}

// After meshing: the vertices a mesh file holds, or those a pole-graded
// sphere adds to cell.target_vertex_count; `mesh_source` names which.
Status check_load_point_vertices(int load_points, std::size_t vertices, std::string_view prefix,
                                 const std::string& mesh_source) {
  if (static_cast<double>(load_points) * static_cast<double>(vertices) <= kMaxLoadPointVertices) return {};
  return invalid_argument(std::string(prefix) + "load_points = " + std::to_string(load_points) +
                          " with the " + std::to_string(vertices) + " vertices of " + mesh_source +
                          " must keep load_points x vertices at most " + number_text(kMaxLoadPointVertices) +
                          " (the run's cost)");
}

// Everything a quasi-static run sets up before its first load step.
struct Setup {
  mesh::TetMesh mesh;  // centred at the origin
  elastic::ElasticBody body;
  std::vector<std::int32_t> surface_vertices;
  std::vector<std::int32_t> surface_triangles;  // filled where the probe acts on the surface
  contact::PenaltyParams penalty;
  double z_top_m = 0.0, z_bottom_m = 0.0;  // extreme surface vertex heights
  // solver::EquilibriumOptions::lagged_tangent_contraction of the run (0: a
  // fresh tangent every Newton iteration)
  double lagged_tangent_contraction = 0.0;
  bool quadratic_predictor = false;  // solver::LoadPath::set_quadratic_predictor (the probe curves)
};

// Indentation: Newton keeps the elastic tangent of the last assembly while
// each iteration contracts the residual at least this much (measurement in
// physics/solver/equilibrium.cc; with the quadratic predictor the probe
// curves take 15 % (colloidal) and 18 % (small probe) less CPU).
// Compression keeps the fresh tangent: the w = 0.25 plates curve, whose
// branch change past 0.66 takes up to 200 Newton iterations a point, took
// 28.1 s CPU with it against 19.8 s without (one run each; w = 1: 4.4 /
// 4.5 s, w = 0.5: 8.2 / 10.3 s; validation/fe/compare_cellflow.py, errors
// unchanged).
constexpr double kIndentationLaggedTangentContraction = 0.3;

StatusOr<Setup> prepare(const cell::CellParams& cell, const QuasiStaticOptions& numerics, int load_points,
                        std::string_view prefix, double pole_spacing_m) {
  Setup setup;
  // The cell mesh with its bounding box centred at the origin, and its body.
  const mesh::PoleGrading grading{.pole_spacing_m = pole_spacing_m,
                                  .growth = numerics.pole_grading_growth,
                                  .ring_jitter = numerics.pole_ring_jitter};
  const bool quadratic = numerics.element == elastic::Element::kQuadraticTet;
  StatusOr<cell::CellBody> built = cell::build_cell_body(
      cell, quadratic ? elastic::VolumetricTerm::kPerTet : numerics.volumetric, std::string(prefix) + "cell.",
      cell::Centring::kBoundingBox, grading, numerics.element);
  if (!built.ok()) return built.status();
  const std::string p(prefix);
  const std::string mesh_source =
      !cell.mesh_file.empty() ? p + "cell.mesh_file"
      : pole_spacing_m > 0.0
          ? "the sphere mesh of " + p + "cell.target_vertex_count graded to " + p + "numerics.pole_spacing_m"
          : "the sphere mesh of " + p + "cell.target_vertex_count";
  if (Status s = check_load_point_vertices(load_points, built->mesh.num_vertices(), prefix, mesh_source);
      !s.ok())
    return s;
  setup.mesh = std::move(built->mesh);
  setup.body = std::move(built->body);
  mesh::TetMesh& m = setup.mesh;
  setup.z_top_m = 0.5 * built->extent_m[2];
  setup.z_bottom_m = -setup.z_top_m;
  for (std::size_t v = 0; v < m.num_vertices(); ++v) {
    if (m.on_surface[v]) setup.surface_vertices.push_back(static_cast<std::int32_t>(v));
  }
  const mesh::MeshQuality quality = mesh::mesh_quality(m);
  // The penalty is sized per contact node: the quadratic mesh's nodes are
  // half an edge apart.
  const double node_spacing_m = quality.mean_edge_length_m * (quadratic ? 0.5 : 1.0);
  setup.penalty = contact::default_penalty(cell.material.youngs_modulus_pa, cell.radius_m, node_spacing_m);
  if (numerics.contact_range_m) {
    // keep the default's force at zero gap (k r) when only the range is given
    const double force_at_contact = setup.penalty.stiffness_n_per_m * setup.penalty.range_m;
    setup.penalty.range_m = *numerics.contact_range_m;
    setup.penalty.stiffness_n_per_m = force_at_contact / setup.penalty.range_m;
  }
  if (numerics.contact_stiffness_n_per_m)
    setup.penalty.stiffness_n_per_m = *numerics.contact_stiffness_n_per_m;
  return setup;
}

// The plates' penalty law at deformation eps = travel / (2R). The vertices in
// contact sit a depth s <= r inside the range, so the cell is compressed by
// the travel minus about 2 s: a relative force error of about
// (2 s / travel) d ln F / d ln eps, and the local exponent d ln F / d ln eps
// grows from 1.5 (Hertz) to 8-10 at eps = 0.8 (validation/fe/README.md).
// Measured with the fixed range r0 = 5e-3 R (3000 vertices, 40 points): the
// force-weighted depth is 0.1 r0 at eps 0.08, 0.3 r0 at 0.64, 0.7 r0 at 0.8;
// it explains the -2.4 % (w = 1) and -4.2 % (w = 0.5) against CalculiX near
// eps = 0.8, and with the compression corrected by it the w = 0.25 curve is
// within 0.6 % of CalculiX up to 0.64. At small eps the range smooths the
// entry of each ring of vertices into the contact (r = 5e-4 R throughout:
// +2.6 % at eps = 0.02 against +0.95 %), so the default r0 is kept up to
// kFullRangeDeformation and then shrinks as r0 eps_full / eps (2 s / travel
// below r0 eps_full / (R eps^2)), with k r fixed (the force where a vertex
// reaches the law's zero gap), so the penetration beyond the range shrinks
// too. A narrower range costs Newton iterations where the cell changes state
// (w = 0.5 at 0.76): eps_full 0.1 / 0.15 / 0.2 give w = 0.5 a largest error
// of 1.60 / 1.79 / 1.99 % at 1.51 / 1.25 / 1.3 x the CPU time of the fixed
// range (bench_compression, alternating with the fixed-range build).
constexpr double kFullRangeDeformation = 0.15;

contact::PenaltyParams plate_penalty_at(const contact::PenaltyParams& base, double deformation) {
  if (deformation <= kFullRangeDeformation) return base;
  const double factor = kFullRangeDeformation / deformation;
  contact::PenaltyParams p = base;
  p.range_m = base.range_m * factor;
  p.stiffness_n_per_m = base.stiffness_n_per_m / factor;
  return p;
}

// Distance of the obstacles' starting surfaces from the cell: the zero-force
// distance of the law (hard contact with the augmented Lagrangian).
double start_distance(const Setup& setup, const QuasiStaticOptions& numerics) {
  return numerics.contact_enforcement == ContactEnforcement::kAugmentedLagrangian ? 0.0
                                                                                  : setup.penalty.range_m;
}

// Height of the cell's bounding box.
double cell_extent(const Setup& setup) {
  return setup.z_top_m - setup.z_bottom_m;
}

// Threads that pay for a solve of this size when the caller asked for none in
// particular (numerics.threads = 0). Measured with idle threads waiting
// passively (2-core machine, 2026-12-01, cellflow-run -j N): 3000 vertices,
// 40 points to 0.5, 1 thread 3.44 s against 2 threads 4.49 s; 12000
// vertices, 6 points to 0.3, 6.90 s against 5.87 s. Below the crossover the
// team's wake-ups cost more than the second core gives. Since the linear
// solve is one parallel region (solver/pcg.cc), 2 threads beat 1 on the
// issue's 3000-vertex curve under load (26.7 s against 31.6 s, load 9) but
// not on the 40 points to 0.5 (equal). Since the two-barrier CG and the
// locality-ordered mesh with its 2-thread assembly (2026-12-03), 2 threads
// asked for (-j 2) take 0.62 of the 1-thread time on the 40 points to 0.5,
// median of 6 rounds; but on a VM whose host steals a vCPU (steal ticks of
// 3-19 s in a 5-20 s run) a 2-thread team took 2-2.5 x the 1-thread time
// while the 1-thread run slowed by ~10 %: one thread stays the choice below
// the crossover, where the second core gives the least.
constexpr std::size_t kMinVerticesForThreads = 6000;

int solve_threads(int requested, std::size_t vertices) {
  if (requested > 0) return requested;
  return vertices < kMinVerticesForThreads ? 1 : 0;  // 0: the OpenMP default
}

solver::EquilibriumOptions solver_options(const QuasiStaticOptions& numerics, const cell::CellParams& cell,
                                          std::size_t vertices) {
  solver::EquilibriumOptions o;
  o.residual_tolerance = numerics.residual_tolerance;
  o.max_newton_iterations = numerics.max_newton_iterations;
  // E R^2: the force scale of the cell (Hertz: F = (4/3) E* R^2 eps^1.5)
  o.force_scale_n = cell.material.youngs_modulus_pa * cell.radius_m * cell.radius_m;
  o.threads = solve_threads(numerics.threads, vertices);
  return o;
}

// Runs the load points of a quasi-static scene. `measure` fills the
// scene-specific fields (force, Hertz) of a point from the converged state.
template <class Measure>
QuasiStaticResult run_load_points(Setup& setup, const cell::CellParams& cell,
                                  const QuasiStaticOptions& numerics, solver::ObstaclesAtLoad obstacles,
                                  double max_travel_m, int load_points, const SceneCallbacks& callbacks,
                                  Measure measure) {
  QuasiStaticResult result;
  if (callbacks.on_mesh) callbacks.on_mesh(setup.mesh);
  solver::EquilibriumOptions options = solver_options(numerics, cell, setup.mesh.num_vertices());
  options.lagged_tangent_contraction = setup.lagged_tangent_contraction;
  solver::EquilibriumSolver solver(setup.body, setup.surface_vertices, setup.mesh.positions_m, options,
                                   setup.surface_triangles);
  solver::ContactEnforcement enforcement;
  enforcement.augmented_lagrangian = numerics.contact_enforcement == ContactEnforcement::kAugmentedLagrangian;
  enforcement.gap_tolerance_m =
      numerics.contact_gap_tolerance_m.value_or(kDefaultGapToleranceRadii * cell.radius_m);
  solver::LoadPath path(solver, std::move(obstacles), setup.mesh.positions_m, 0.0, enforcement);
  const double diameter = 2.0 * cell.radius_m;
  // The volumetric energy kappa/2 (J - 1)^2 of eq. (5) carries at most the
  // pressure kappa (1 - J) <= kappa: under a large enough load an element
  // gives up its volume at bounded cost and the curve drops, converged but
  // wrong (seen at deformation 0.81 with nu = 0.45, w = 0.5), or the
  // equilibrium path loses stability and Newton fails (nu = 0.45, w = 1 at
  // 0.897, where CalculiX's axisymmetric reference of the same energy has
  // min J 0.19). A converged state, load point or sub-step, with an element
  // below kMinVolumeRatio ends the run naming it.
  path.set_quadratic_predictor(setup.quadratic_predictor);
  path.set_state_check([&setup, diameter](double load_m, std::span<const double> positions_m) -> std::string {
    const elastic::VolumeRatioMinimum crushed = elastic::min_volume_ratio(setup.body, positions_m.data());
    if (!(crushed.volume_ratio < kMinVolumeRatio)) return {};
    return "tetrahedron " + std::to_string(crushed.tet) +
           " is compressed to J = " + number_text(crushed.volume_ratio) + " of its volume (below " +
           number_text(kMinVolumeRatio) + ") at deformation " + number_text(load_m / diameter) +
           ": the volumetric energy of eq. 5 no longer holds the volume; the curve ends before it";
  });
  for (int i = 0; i < load_points; ++i) {
    if (callbacks.should_stop && callbacks.should_stop()) {
      result.status =
          Status(StatusCode::kCancelled, "stopped on request before load point " + std::to_string(i));
      return result;
    }
    const double travel = max_travel_m * (i + 1) / load_points;
    const solver::LoadStepReport step = path.advance_to(travel, numerics.max_step_splits);
    if (!step.converged) {
      result.status =
          numerical_failure("load step " + std::to_string(i) + " of " + std::to_string(load_points) +
                            " (target deformation " + number_text(travel / diameter) + "): " + step.message);
      return result;
    }
    CurvePoint point;
    point.index = i;
    point.deformation = travel / diameter;
    point.displacement_m = travel;
    const std::vector<double>& y = path.positions_m();
    measure(step.last, travel, point);
    if (!result.curve.empty() && point.force_n < (1.0 - kMaxForceDrop) * result.curve.back().force_n) {
      const double spacing = mesh::mesh_quality(setup.mesh).mean_edge_length_m;
      result.status = numerical_failure(
          "load step " + std::to_string(i) + " of " + std::to_string(load_points) + " (target deformation " +
          number_text(travel / diameter) + "): the force fell from " +
          number_text(result.curve.back().force_n) + " N to " + number_text(point.force_n) +
          " N with more travel: the obstacle slipped between surface vertices (mean mesh edge " +
          number_text(spacing) +
          " m); the curve ends before it. Raise cell.target_vertex_count, or use a probe much wider than "
          "the mesh edge");
      return result;
    }
    const observables::Shape shape = observables::measure_shape(setup.mesh, y.data());
    point.taylor_deformation = shape.taylor_deformation;
    for (int a = 0; a < 3; ++a) point.semi_axes_m[a] = shape.semi_axes_m[a];
    point.volume_m3 = shape.volume_m3;
    point.elastic_energy_j = step.last.elastic_energy_j;
    point.max_penetration_m = step.last.contact.max_penetration_m;
    point.gap_error_m = step.gap_error_m;
    point.contact_updates = step.contact_updates;
    point.newton_iterations = step.newton_iterations;
    point.cg_iterations = step.cg_iterations;
    point.step_splits = step.step_splits;
    point.residual = step.last.residual;
    result.curve.push_back(point);
    if (callbacks.on_point) callbacks.on_point(point);
    if (callbacks.on_positions) callbacks.on_positions(i, y);
    if (callbacks.on_progress) callbacks.on_progress(static_cast<double>(i + 1) / load_points);
  }
  return result;
}

}  // namespace

double default_pole_spacing_m(const IndentationParams& params) {
  const double radius = params.cell.radius_m;
  const double rp = params.probe_radius_m;
  if (!params.cell.mesh_file.empty() || params.cell.mesh_bytes || !(radius > 0.0 && rp > 0.0) ||
      params.load_points < 1)
    return 0.0;
  // Hertz contact radii a = sqrt(R d) of the first load point (paper SI
  // section 2.5; Johnson, Contact Mechanics, eq. 4.22): probe on top
  // (R12 = Rp R / (Rp + R)), plate below (R); the travel split as in
  // hertz_probe_force_n.
  const double travel = params.max_indentation_m / params.load_points;
  const double r12 = rp * radius / (rp + radius);
  const double d_top = travel / (1.0 + std::cbrt(r12 / radius));
  const double contact_radius = std::min(std::sqrt(r12 * d_top), std::sqrt(radius * (travel - d_top)));
  const double uniform = mesh::sphere_mesh_spacing_m(radius, params.cell.target_vertex_count);
  const double wanted = contact_radius / kPoleSpacingsPerContactRadius;
  if (!(wanted < uniform)) return 0.0;
  return std::max({wanted, uniform / kMaxDefaultPoleRefinement, kMinPoleSpacingRadii * radius});
}

Violations violations(const CompressionParams& params) {
  Violations v;
  v.add_all(cell::check(params.cell), "cell.");
  if (!(params.max_deformation > 0.0 && params.max_deformation <= kMaxDeformation)) {
    v.add_value("max_deformation", params.max_deformation,
                "lie in (0, " + number_text(kMaxDeformation) + "]");
  } else if (!(params.max_deformation >= kMinDeformation)) {
    v.add_value("max_deformation", params.max_deformation, real_range(kMinDeformation, kMaxDeformation));
  }
  check_load_points(params.load_points, params.cell, v);
  v.add_all(check_numerics(params.numerics, params.cell), "numerics.");
  return v;
}

Violations violations(const IndentationParams& params) {
  Violations v;
  v.add_all(cell::check(params.cell), "cell.");
  const double radius = params.cell.radius_m;
  const double rp = params.probe_radius_m;
  if (!(rp > 0.0 && std::isfinite(rp))) {
    v.add_value("probe_radius_m", rp, "be > 0 and finite");
  } else if (!(rp >= kMinProbeRadiusM && rp <= kMaxProbeRadiusM)) {
    v.add_value("probe_radius_m", rp, real_range(kMinProbeRadiusM, kMaxProbeRadiusM) + " m");
  } else if (!(rp >= kMinProbeRadii * radius && rp <= kMaxProbeRadii * radius)) {
    v.add_value("probe_radius_m", rp,
                "lie in [" + number_text(kMinProbeRadii) + " cell.radius_m, " + number_text(kMaxProbeRadii) +
                    " cell.radius_m] = " + interval(kMinProbeRadii * radius, kMaxProbeRadii * radius));
  }
  const double max_travel = kMaxIndentationRadii * radius;
  const double min_travel = kMinDeformation * 2.0 * radius;
  if (!(params.max_indentation_m > 0.0 && params.max_indentation_m < max_travel)) {
    v.add_value("max_indentation_m", params.max_indentation_m,
                "lie in (0, " + number_text(kMaxIndentationRadii) + " cell.radius_m) = (0, " +
                    number_text(max_travel) + ")");
  } else if (!(params.max_indentation_m >= min_travel)) {
    v.add_value("max_indentation_m", params.max_indentation_m,
                "lie in [" + number_text(2.0 * kMinDeformation) + " cell.radius_m, " +
                    number_text(kMaxIndentationRadii) + " cell.radius_m) = [" + number_text(min_travel) +
                    ", " + number_text(max_travel) + ")");
  }
  check_load_points(params.load_points, params.cell, v);
  v.add_all(check_numerics(params.numerics, params.cell), "numerics.");
  return v;
}

Status validate(const CompressionParams& params, std::string_view field_prefix) {
  return violations(params).status(field_prefix);
}

Status validate(const IndentationParams& params, std::string_view field_prefix) {
  return violations(params).status(field_prefix);
}

StatusOr<Checked<CompressionParams>> check(const CompressionParams& params, std::string_view field_prefix) {
  if (Status s = validate(params, field_prefix); !s.ok()) return s;
  return Checked<CompressionParams>(params);
}

StatusOr<Checked<IndentationParams>> check(const IndentationParams& params, std::string_view field_prefix) {
  if (Status s = validate(params, field_prefix); !s.ok()) return s;
  return Checked<IndentationParams>(params);
}

QuasiStaticResult run_compression(const CompressionParams& params, const SceneCallbacks& callbacks) {
  StatusOr<Checked<CompressionParams>> checked = check(params);
  if (!checked.ok()) return QuasiStaticResult{.status = checked.status(), .curve = {}};
  return run_compression(*checked, callbacks);
}

QuasiStaticResult run_indentation(const IndentationParams& params, const SceneCallbacks& callbacks) {
  StatusOr<Checked<IndentationParams>> checked = check(params);
  if (!checked.ok()) return QuasiStaticResult{.status = checked.status(), .curve = {}};
  return run_indentation(*checked, callbacks);
}

QuasiStaticResult run_compression(const Checked<CompressionParams>& checked,
                                  const SceneCallbacks& callbacks) {
  const CompressionParams& params = checked.params();
  StatusOr<Setup> prepared = prepare(params.cell, params.numerics, params.load_points, "compression.",
                                     params.numerics.pole_spacing_m.value_or(0.0));
  if (!prepared.ok()) return QuasiStaticResult{.status = prepared.status(), .curve = {}};
  Setup& setup = *prepared;
  // Plates start at the zero-force distance from the extreme vertices: first
  // contact, no force at zero travel. That is the surface itself with the
  // augmented Lagrangian (hard-contact offsets, no force at gap >= 0), the
  // penalty range with the plain penalty.
  const contact::PenaltyParams penalty = setup.penalty;
  const cell::CellParams& cell = params.cell;
  // The default penalty range shrinks as the compression grows (plain
  // penalty, no range in the spec): see plate_penalty_at.
  const bool shrink_range = params.numerics.contact_enforcement == ContactEnforcement::kPenalty &&
                            !params.numerics.contact_range_m && !params.numerics.contact_stiffness_n_per_m;
  const double diameter = 2.0 * cell.radius_m;
  auto obstacles = [=, &setup, &params](double travel_m) {
    contact::Obstacles o;
    o.penalty = shrink_range ? plate_penalty_at(penalty, travel_m / diameter) : penalty;
    // The plates' surfaces are at the extreme vertices at zero travel; the
    // law's zero-force distance (its range; 0 with the augmented Lagrangian)
    // lies beyond them.
    const double range = params.numerics.contact_enforcement == ContactEnforcement::kAugmentedLagrangian
                             ? 0.0
                             : o.penalty.range_m;
    o.lower_plate_z_m = setup.z_bottom_m - range;
    o.upper_plate_z_m = setup.z_top_m + range - travel_m;
    return o;
  };
  auto measure = [&](const solver::EquilibriumReport& eq, double travel_m, CurvePoint& point) {
    point.force_n = eq.contact.upper_plate_reaction_n;
    point.hertz_force_n = hertz_plates_force_n(cell.material, cell.radius_m, travel_m);
  };
  const double max_travel = params.max_deformation * 2.0 * cell.radius_m;
  return run_load_points(setup, cell, params.numerics, obstacles, max_travel, params.load_points, callbacks,
                         measure);
}

QuasiStaticResult run_indentation(const Checked<IndentationParams>& checked,
                                  const SceneCallbacks& callbacks) {
  const IndentationParams& params = checked.params();
  StatusOr<Setup> prepared = prepare(params.cell, params.numerics, params.load_points, "indentation.",
                                     params.numerics.pole_spacing_m.value_or(default_pole_spacing_m(params)));
  if (!prepared.ok()) return QuasiStaticResult{.status = prepared.status(), .curve = {}};
  Setup& setup = *prepared;
  setup.lagged_tangent_contraction = kIndentationLaggedTangentContraction;
  setup.quadratic_predictor = true;
  const double range = start_distance(setup, params.numerics);
  const double lower_z = setup.z_bottom_m - range;
  if (params.numerics.probe_contact == ProbeContact::kSurface) {
    setup.surface_triangles = contact::boundary_triangles(setup.mesh.tets, setup.mesh.positions_m.data());
    // Quadratic tets: each 6-node face as its four flat sub-triangles.
    if (!setup.mesh.quadratic_tets.empty())
      setup.surface_triangles = mesh::split_at_mid_edge_nodes(setup.mesh, setup.surface_triangles);
  }
  // Probe on the z axis, lowered until its zero-force surface (radius Rp + r)
  // touches the first surface vertex: z_c = max_v z_v + sqrt((Rp + r)^2 - rho_v^2).
  const double reach = params.probe_radius_m + range;
  double centre_z0 = setup.z_top_m + reach;
  double lowest = -1e300;
  for (const std::int32_t v : setup.surface_vertices) {
    const double* p = setup.mesh.positions_m.data() + 3 * static_cast<std::size_t>(v);
    const double rho2 = p[0] * p[0] + p[1] * p[1];
    if (rho2 < reach * reach) lowest = std::max(lowest, p[2] + std::sqrt(reach * reach - rho2));
  }
  if (lowest > -1e300) centre_z0 = lowest;
  const contact::PenaltyParams penalty = setup.penalty;
  const double probe_radius = params.probe_radius_m;
  const std::span<const std::int32_t> triangles = setup.surface_triangles;
  if (!triangles.empty()) {
    // On the surface the first contact is with a triangle, at or above the
    // first vertex: bisect the centre height where the nearest triangle is
    // at the zero-force distance Rp + r (the vertices' height has it at or
    // below, the top of the cell plus Rp + r far above).
    auto nearest = [&](double z) {
      contact::Obstacles o;
      o.penalty = penalty;
      o.probe = contact::Probe{.centre_m = {0.0, 0.0, z}, .radius_m = reach};
      o.probe_triangles = triangles;
      std::vector<double> gaps(triangles.size() / 3), normals(triangles.size()), bary(triangles.size());
      contact::probe_triangle_gaps(o, setup.mesh.positions_m.data(), gaps.data(), normals.data(),
                                   bary.data());
      return *std::min_element(gaps.begin(), gaps.end());
    };
    double low = centre_z0, high = setup.z_top_m + reach + cell_extent(setup);
    if (nearest(low) < 0.0) {
      for (int i = 0; i < 100 && high - low > 1e-12 * reach; ++i) {
        const double middle = 0.5 * (low + high);
        (nearest(middle) < 0.0 ? low : high) = middle;
      }
      centre_z0 = high;
    }
  }
  auto obstacles = [=](double travel_m) {
    contact::Obstacles o;
    o.penalty = penalty;
    o.lower_plate_z_m = lower_z;
    o.probe = contact::Probe{.centre_m = {0.0, 0.0, centre_z0 - travel_m}, .radius_m = probe_radius};
    o.probe_triangles = triangles;
    return o;
  };
  const cell::CellParams& cell = params.cell;
  auto measure = [&](const solver::EquilibriumReport& eq, double travel_m, CurvePoint& point) {
    point.force_n = eq.contact.probe_reaction_n[2];
    point.hertz_force_n = hertz_probe_force_n(cell.material, cell.radius_m, probe_radius, travel_m);
  };
  return run_load_points(setup, cell, params.numerics, obstacles, params.max_indentation_m,
                         params.load_points, callbacks, measure);
}

double hertz_plates_force_n(const elastic::Material& m, double radius_m, double compression_m) {
  // E* = E / (1 - nu^2);  F = (4/3) E* R^2 eps^(3/2), eps = delta / (2R)   (validation/README.md, Hertz)
  const double e_star = m.youngs_modulus_pa / (1.0 - m.poisson_ratio * m.poisson_ratio);
  const double eps = std::max(0.0, compression_m) / (2.0 * radius_m);
  return 4.0 / 3.0 * e_star * radius_m * radius_m * std::pow(eps, 1.5);
}

double hertz_probe_force_n(const elastic::Material& m, double radius_m, double probe_radius_m,
                           double indentation_m) {
  const double e_star = m.youngs_modulus_pa / (1.0 - m.poisson_ratio * m.poisson_ratio);
  // R12 = Rp Rc / (Rp + Rc): the top contact, rigid sphere on the cell
  const double r12 = probe_radius_m * radius_m / (probe_radius_m + radius_m);
  // equal force (4/3) E* sqrt(R12) d_top^1.5 = (4/3) E* sqrt(Rc) d_bottom^1.5
  //   -> d_bottom = d_top (R12 / Rc)^(1/3);  d_top + d_bottom = delta
  const double d_top = std::max(0.0, indentation_m) / (1.0 + std::cbrt(r12 / radius_m));
  return 4.0 / 3.0 * e_star * std::sqrt(r12) * std::pow(d_top, 1.5);
}

}  // namespace cellflow::scenes
