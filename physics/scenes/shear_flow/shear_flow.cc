#include "physics/scenes/shear_flow/shear_flow.h"

#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "physics/cell/cell_body.h"
#include "physics/coupling/immersed_cell.h"
#include "physics/elastic/elastic_body.h"
#include "physics/elastic/material.h"
#include "physics/lb/fluid.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"
#include "physics/observables/shape.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string num(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

void add_violation(std::string& message, std::string_view text) {
  if (!message.empty()) message += "; ";
  message += text;
}

bool positive_finite(double v) {
  return v > 0.0 && std::isfinite(v);
}

// Elastic energy above this multiple of mu V0 is a blow-up: the paper's
// largest deformation (strain 1.8 at Ca = 2) stores about 3 mu V0.
constexpr double kEnergyBlowUp = 100.0;

// A vertex faster than this (lattice units, Mach 0.35) means the explicit
// coupling has gone unstable; the flow itself never exceeds u_wall.
constexpr double kRunawaySpeedLattice = 0.2;

// Surface vertices within this fraction of R of the equatorial plane z = 0
// (reference configuration) carry the tank-treading estimate: their angle in
// the x-y plane about the centroid is well defined.
constexpr double kTankTreadBand = 0.7;

// Vertex count from which the coupling kernels use OpenMP threads (3000
// vertices: elastic forces 0.56 ms serial, 0.37 ms on two free cores).
constexpr std::size_t kParallelVertices = 2000;

// Smallest box (in radii) that holds the cell and the support of its
// immersed-boundary kernel: periodic directions need the cell and its image
// apart by one kernel width; the wall direction needs half a kernel width
// plus one spacing on each side.
double min_box_periodic_radii(const ShearFlowNumerics& n) {
  return 2.0 + ibm::kernel_width(n.ibm_kernel) / n.cells_per_radius;
}
double min_box_wall_radii(const ShearFlowNumerics& n) {
  return 2.0 + (ibm::kernel_width(n.ibm_kernel) + 2.0) / n.cells_per_radius;
}

double shear_modulus(const elastic::Material& material) {
  const elastic::Moduli m = elastic::moduli_from(material);
  return m.mu1_pa + m.mu2_pa;
}

// Everything plan_shear_flow derives, with the conversion object.
struct Plan {
  ShearFlowSetup setup;
  units::Units units{1.0, 1.0, 1.0, 1.0};
};

StatusOr<Plan> make_plan(const ShearFlowParams& params, std::string_view field_prefix) {
  if (Status s = validate(params, field_prefix); !s.ok()) return s;
  const std::string prefix(field_prefix);
  const std::string numerics_prefix = prefix + "numerics.";
  const ShearFlowNumerics& n = params.numerics;
  Plan plan;
  ShearFlowSetup& setup = plan.setup;
  const double radius = params.cell.radius_m;
  const double eta = params.fluid_viscosity_pa_s;
  setup.shear_modulus_pa = shear_modulus(params.cell.material);
  if (params.capillary_number > 0.0) {
    setup.capillary_number = params.capillary_number;
    // gammadot = Ca mu / eta   (paper eq. 17 solved for the shear rate)
    setup.shear_rate_per_s = params.capillary_number * setup.shear_modulus_pa / eta;
  } else {
    setup.shear_rate_per_s = params.shear_rate_per_s;
    // Ca = eta gammadot / mu   (paper eq. 17)
    setup.capillary_number = eta * params.shear_rate_per_s / setup.shear_modulus_pa;
  }
  const double gammadot = setup.shear_rate_per_s;
  // Re_p = rho gammadot R^2 / eta
  setup.reynolds_number_physical = params.fluid_density_kg_m3 * gammadot * radius * radius / eta;
  setup.simulated_density_kg_m3 = params.fluid_density_kg_m3;
  if (n.target_reynolds_number > 0.0 && setup.reynolds_number_physical < n.target_reynolds_number) {
    // rho_sim = Re_target eta / (gammadot R^2)
    setup.simulated_density_kg_m3 = n.target_reynolds_number * eta / (gammadot * radius * radius);
  }
  setup.reynolds_number_simulated = setup.simulated_density_kg_m3 * gammadot * radius * radius / eta;

  units::LatticeChoice choice;
  choice.cell_radius_m = radius;
  choice.cells_per_radius = n.cells_per_radius;
  choice.relaxation_time = n.relaxation_time;
  choice.fluid_density_kg_m3 = setup.simulated_density_kg_m3;
  choice.fluid_viscosity_pa_s = eta;
  StatusOr<units::Units> made = units::make_units(choice, numerics_prefix);
  if (!made.ok()) return made.status();
  plan.units = *made;
  const units::Units& u = plan.units;
  setup.lattice_spacing_m = u.dx_m();
  setup.time_step_s = u.dt_s();
  setup.nx = units::nodes_along(u, n.box_x_radii * radius);
  setup.ny = units::nodes_along(u, n.box_y_radii * radius);
  setup.nz = units::nodes_along(u, n.box_z_radii * radius);
  setup.box_m[0] = u.length_to_si(setup.nx);
  setup.box_m[1] = u.length_to_si(setup.ny);
  setup.box_m[2] = u.length_to_si(setup.nz);
  // u_wall = H gammadot / 2 with the lattice's exact wall distance H = ny dx   (paper section 7.1)
  setup.wall_speed_m_per_s = 0.5 * setup.box_m[1] * gammadot;
  // Ma = u_wall / c_s, c_s = 1 / sqrt(3) in lattice units
  setup.mach_number = std::abs(u.velocity_to_lattice(setup.wall_speed_m_per_s)) * std::sqrt(3.0);
  setup.shear_rate_lattice = u.shear_rate_to_lattice(gammadot);
  setup.steps_per_strain = 1.0 / setup.shear_rate_lattice;

  units::StabilityLimits limits;
  limits.max_mach = n.max_mach;
  if (Status s = units::validate_lattice(u, choice, setup.wall_speed_m_per_s, limits, numerics_prefix);
      !s.ok()) {
    std::string message = s.message();
    if (setup.simulated_density_kg_m3 > params.fluid_density_kg_m3) {
      // With the density raised, u_wall,lb = (H / 2R) Re nu_lb / cells_per_radius.
      message += ", or lower " + numerics_prefix + "target_reynolds_number (now " +
                 num(n.target_reynolds_number) + ")";
    }
    return Status(s.code(), std::move(message));
  }
  setup.lattice_bytes = units::estimate_lattice_bytes(setup.nx, setup.ny, setup.nz, n.single_precision);
  if (Status s = units::check_memory(setup.lattice_bytes, n.memory_limit_bytes, numerics_prefix); !s.ok())
    return s;
  return plan;
}

// Largest eigenvalue of the elastic tangent stiffness at the reference
// configuration (N/m) by power iteration: the stiffest vertex mode.
double stiffest_mode(const elastic::ElasticBody& body, const std::vector<double>& positions_m, int threads) {
  elastic::TangentAssembler assembler(body);
  assembler.set_threads(threads);
  assembler.assemble(positions_m.data());
  Eigen::VectorXd v(assembler.stiffness().rows()), w(v.size());
  // Deterministic start with components in every mode.
  for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = std::sin(1.0 + 0.7 * static_cast<double>(i));
  v.normalize();
  double lambda = 0.0;
  for (int it = 0; it < 200; ++it) {
    assembler.multiply(v.data(), w.data());  // K v, with the applied volumetric part if any
    const double next = v.dot(w);            // Rayleigh quotient, v normalised
    const double norm = w.norm();
    if (!(norm > 0.0)) break;
    v = w / norm;
    if (it > 20 && std::abs(next - lambda) < 1e-4 * std::abs(next)) {
      lambda = next;
      break;
    }
    lambda = next;
  }
  return lambda;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// State of one run.
struct Run {
  const ShearFlowParams* params = nullptr;
  const ShearFlowCallbacks* callbacks = nullptr;
  Plan plan;
  mesh::TetMesh mesh;
  elastic::ElasticBody body;
  // The immersed cells: one, at the box centre (no cell-cell contact is built).
  coupling::ImmersedCells cells;
  std::vector<double> x_si;             // box coordinates in metres, at samples
  std::vector<double> last_good_x_lb;   // at the last sample
  std::vector<int> tank_vertices;       // surface vertices near z = 0
  std::vector<double> tank_angle;       // last angle of each, rad
  std::vector<double> tank_unwrapped;   // accumulated angle of each, rad
  std::vector<double> tank_mean_angle;  // per sample: mean accumulated angle
  double energy_limit_j = 0.0;
  double last_energy_j = 0.0;
  int snapshot_index = 0;
};

void to_si(Run& run) {
  const double dx = run.plan.units.dx_m();
  const std::vector<double>& x = run.cells[0].positions_lattice;
  for (std::size_t i = 0; i < x.size(); ++i) run.x_si[i] = x[i] * dx;
}

void emit_positions(Run& run, double time_s, const std::vector<double>& x_lb) {
  if (!run.callbacks->on_positions) return;
  const double dx = run.plan.units.dx_m();
  std::vector<double> positions(x_lb.size());
  for (std::size_t i = 0; i < x_lb.size(); ++i) positions[i] = x_lb[i] * dx;
  run.callbacks->on_positions(run.snapshot_index, time_s, positions);
}

template <class T>
void emit_fluid(Run& run, const lb::Fluid& fluid, int index, double time_s) {
  if (!run.callbacks->on_fluid_velocity || !run.params->numerics.fluid_snapshots) return;
  const lb::VectorField<const T> u = fluid.velocity_field<T>();
  const std::size_t n = fluid.num_nodes();
  const double scale = run.plan.units.velocity_to_si(1.0);
  std::vector<double> ux(n), uy(n), uz(n);
  for (std::size_t i = 0; i < n; ++i) {
    ux[i] = scale * static_cast<double>(u.x[i]);
    uy[i] = scale * static_cast<double>(u.y[i]);
    uz[i] = scale * static_cast<double>(u.z[i]);
  }
  FluidVelocitySnapshot snap;
  snap.index = index;
  snap.time_s = time_s;
  snap.nx = fluid.nx();
  snap.ny = fluid.ny();
  snap.nz = fluid.nz();
  snap.spacing_m = run.plan.units.dx_m();
  snap.ux_m_per_s = ux;
  snap.uy_m_per_s = uy;
  snap.uz_m_per_s = uz;
  run.callbacks->on_fluid_velocity(snap);
}

// Observables at the current positions; appends the sample.
ShearFlowSample take_sample(Run& run, ShearFlowResult& result, std::int64_t step) {
  to_si(run);
  const observables::Shape shape = observables::measure_shape(run.mesh, run.x_si.data());
  ShearFlowSample s;
  s.index = static_cast<int>(result.samples.size());
  s.time_step = step;
  s.time_s = run.plan.units.time_to_si(static_cast<double>(step));
  s.strain_units = static_cast<double>(step) * run.plan.setup.shear_rate_lattice;
  s.taylor_deformation = shape.taylor_deformation;
  s.inclination_deg = shape.inclination_rad * 180.0 / kPi;
  s.net_strain = observables::net_strain(run.mesh, run.x_si.data(), 2.0 * run.params->cell.radius_m);
  s.semi_axes_m = shape.semi_axes_m;
  s.centroid_m = shape.centroid_m;
  s.volume_m3 = shape.volume_m3;
  s.elastic_energy_j = run.last_energy_j;

  // Tank treading: unwrapped angle of each tracked surface vertex about the
  // centroid in the x-y plane; the mean accumulated angle per sample.
  double mean = 0.0;
  for (std::size_t t = 0; t < run.tank_vertices.size(); ++t) {
    const int v = run.tank_vertices[t];
    const double angle =
        std::atan2(run.x_si[3 * v + 1] - shape.centroid_m[1], run.x_si[3 * v] - shape.centroid_m[0]);
    double delta = angle - run.tank_angle[t];
    delta -= 2.0 * kPi * std::round(delta / (2.0 * kPi));
    if (!result.samples.empty()) run.tank_unwrapped[t] += delta;
    run.tank_angle[t] = angle;
    mean += run.tank_unwrapped[t];
  }
  if (!run.tank_vertices.empty()) mean /= static_cast<double>(run.tank_vertices.size());
  run.tank_mean_angle.push_back(mean);
  const ShearFlowNumerics& n = run.params->numerics;
  const int window =
      std::max(1, static_cast<int>(std::lround(n.steady_window_strain / n.sample_every_strain)));
  const int first = std::max(0, s.index - window);
  if (s.index > first) {
    const ShearFlowSample& start = result.samples[first];
    // clockwise (the sense of the shear vorticity) positive
    s.tank_treading_frequency_per_s =
        -(run.tank_mean_angle[s.index] - run.tank_mean_angle[first]) / (s.time_s - start.time_s);
  }
  result.samples.push_back(s);
  return s;
}

// Means over the last window of samples; the relative change of D there.
void summarise(const Run& run, ShearFlowResult& result) {
  if (result.samples.empty()) return;
  const ShearFlowNumerics& n = run.params->numerics;
  const int window =
      std::max(1, static_cast<int>(std::lround(n.steady_window_strain / n.sample_every_strain)));
  const int last = static_cast<int>(result.samples.size()) - 1;
  const int first = std::max(0, last - window);
  double d_sum = 0.0, incl_sum = 0.0, strain_sum = 0.0;
  double d_min = std::numeric_limits<double>::max(), d_max = -d_min;
  for (int i = first; i <= last; ++i) {
    const ShearFlowSample& s = result.samples[i];
    d_sum += s.taylor_deformation;
    incl_sum += s.inclination_deg;
    strain_sum += s.net_strain;
    d_min = std::min(d_min, s.taylor_deformation);
    d_max = std::max(d_max, s.taylor_deformation);
  }
  const double count = static_cast<double>(last - first + 1);
  result.steady_taylor_deformation = d_sum / count;
  result.steady_inclination_deg = incl_sum / count;
  result.steady_net_strain = strain_sum / count;
  result.steady_relative_change =
      result.steady_taylor_deformation > 0.0 ? (d_max - d_min) / result.steady_taylor_deformation : 0.0;
  result.tank_treading_frequency_per_s = result.samples[last].tank_treading_frequency_per_s;

  // Thickness 2 a1 against the kernel width kernel_width dx.
  const double kernel_m = ibm::kernel_width(n.ibm_kernel) * run.plan.units.dx_m();
  result.thickness_over_kernel = 2.0 * result.samples[last].semi_axes_m[0] / kernel_m;
  if (result.thickness_over_kernel < kMinThicknessOverKernel) {
    result.warnings.push_back(
        "under-resolved: the cell's thickness 2 a1 = " + num(2.0 * result.samples[last].semi_axes_m[0]) +
        " m is " + num(result.thickness_over_kernel) + " kernel widths (below " +
        num(kMinThicknessOverKernel) +
        "), so D and the strain are overestimated; raise shear_flow.numerics.cells_per_radius to at least " +
        num(std::ceil(n.cells_per_radius * kMinThicknessOverKernel / result.thickness_over_kernel)));
  }
}

// True when D over the last full window changed by less than the tolerance.
bool is_steady(const ShearFlowResult& result, const ShearFlowNumerics& n) {
  if (!(n.steady_tolerance > 0.0)) return false;
  const int window =
      std::max(1, static_cast<int>(std::lround(n.steady_window_strain / n.sample_every_strain)));
  const int last = static_cast<int>(result.samples.size()) - 1;
  if (last < window) return false;
  double d_sum = 0.0;
  double d_min = std::numeric_limits<double>::max(), d_max = -d_min;
  for (int i = last - window; i <= last; ++i) {
    const double d = result.samples[i].taylor_deformation;
    d_sum += d;
    d_min = std::min(d_min, d);
    d_max = std::max(d_max, d);
  }
  const double mean = d_sum / (window + 1);
  // (max D - min D) / mean D < tolerance over the window
  return mean > 0.0 && (d_max - d_min) < n.steady_tolerance * mean;
}

std::string where(const Run& run, std::int64_t step) {
  return "time step " + std::to_string(step) +
         " (t = " + num(run.plan.units.time_to_si(static_cast<double>(step))) + " s, strain " +
         num(static_cast<double>(step) * run.plan.setup.shear_rate_lattice) + ")";
}

template <class T>
void time_loop(Run& run, lb::Fluid& fluid, ShearFlowResult& result) {
  using Clock = std::chrono::steady_clock;
  const ShearFlowNumerics& n = run.params->numerics;
  const ShearFlowCallbacks& cb = *run.callbacks;
  const ShearFlowSetup& setup = run.plan.setup;
  const ibm::Kernel kernel = n.ibm_kernel;
  const int width = ibm::kernel_width(kernel);
  const int threads = n.threads;
  // Below kParallelVertices the coupling kernels run serial: OpenMP fork/join
  // costs more than the work (bench/shear_flow: 1000 vertices, 0.4 ms serial).
  const int coupling_threads = run.mesh.num_vertices() >= kParallelVertices ? threads : 1;
  const double dx = run.plan.units.dx_m();
  coupling::ImmersedCells& cells = run.cells;
  const coupling::ImmersedCell& cell = cells[0];  // the cell the observables follow

  const std::int64_t sample_steps =
      std::max<std::int64_t>(1, std::llround(n.sample_every_strain * setup.steps_per_strain));
  const std::int64_t snapshot_steps =
      n.snapshot_every_strain > 0.0
          ? std::max<std::int64_t>(1, std::llround(n.snapshot_every_strain * setup.steps_per_strain))
          : 0;
  std::int64_t max_steps = static_cast<std::int64_t>(std::ceil(n.max_strain * setup.steps_per_strain));
  ShearFlowStop limit_stop = ShearFlowStop::kMaxStrain;
  if (n.max_time_s > 0.0) {
    const auto time_steps =
        static_cast<std::int64_t>(std::ceil(run.plan.units.time_to_lattice(n.max_time_s)));
    if (time_steps < max_steps) {
      max_steps = time_steps;
      limit_stop = ShearFlowStop::kMaxTime;
    }
  }
  // Walls: a vertex closer than half a kernel width loses force into the wall.
  const double wall_margin = 0.5 * width;

  auto fail = [&](std::int64_t step, const std::string& cause) {
    result.status = numerical_failure(where(run, step) + ": " + cause);
    result.stop = ShearFlowStop::kFailed;
    result.time_steps = step;
    run.snapshot_index++;
    emit_positions(run, run.plan.units.time_to_si(static_cast<double>(result.samples.back().time_step)),
                   run.last_good_x_lb);
  };

  std::int64_t step = 0;
  // Sample and snapshot at t = 0.
  {
    const auto t0 = Clock::now();
    to_si(run);
    run.last_energy_j = elastic::elastic_energy(run.body, run.x_si.data(), coupling_threads).energy_j;
    const ShearFlowSample s = take_sample(run, result, 0);
    run.last_good_x_lb = cell.positions_lattice;
    if (cb.on_sample) cb.on_sample(s);
    if (snapshot_steps > 0) {
      emit_positions(run, 0.0, cell.positions_lattice);
      emit_fluid<T>(run, fluid, run.snapshot_index, 0.0);
    }
    result.observables_s += seconds_since(t0);
  }
  while (true) {
    if (step >= max_steps) {
      result.stop = limit_stop;
      break;
    }
    // Elastic forces at the vertices.
    const auto t0 = Clock::now();
    const std::vector<elastic::ElasticEvaluation> evals =
        coupling::compute_elastic_forces(cells, coupling_threads);
    for (const elastic::ElasticEvaluation& eval : evals) {
      if (eval.first_inverted_tet >= 0) {
        fail(step, "tetrahedron " + std::to_string(eval.first_inverted_tet) +
                       " inverted (J <= 0); the explicit update is unstable or the deformation too large");
        return;
      }
      if (!(eval.energy_j <= run.energy_limit_j)) {
        fail(step, "elastic energy " + num(eval.energy_j) + " J exceeds " + num(kEnergyBlowUp) +
                       " mu V0 = " + num(run.energy_limit_j) + " J (blow-up or NaN)");
        return;
      }
    }
    run.last_energy_j = evals[0].energy_j;
    const auto t1 = Clock::now();
    result.elastic_s += std::chrono::duration<double>(t1 - t0).count();

    // Spread onto the lattice (only the nodes near the cell are cleared).
    coupling::spread_forces(cells, fluid, kernel, coupling_threads);
    const auto t2 = Clock::now();
    result.coupling_s += std::chrono::duration<double>(t2 - t1).count();

    // Collide and stream; the velocity field u(t) of this step is written.
    lb::collide_stream(fluid);
    const auto t3 = Clock::now();
    result.lattice_s += std::chrono::duration<double>(t3 - t2).count();

    // Interpolate u(t) at the vertices and move them: X += U dt.
    const std::vector<coupling::AdvectReport> reports =
        coupling::advect_cells(cells, fluid, kernel, coupling_threads);
    ++step;
    result.coupling_s += seconds_since(t3);
    for (const coupling::AdvectReport& moved : reports) {
      if (!std::isfinite(moved.max_speed_lattice)) {
        fail(step, "vertex velocity is NaN");
        return;
      }
      if (moved.max_speed_lattice > kRunawaySpeedLattice) {
        fail(step, "vertex speed " + num(moved.max_speed_lattice) + " (lattice units) exceeds " +
                       num(kRunawaySpeedLattice) + " (wall speed " + num(setup.mach_number / std::sqrt(3.0)) +
                       "): the explicit coupling is unstable; lower shear_flow.numerics.max_stiffness_ratio, "
                       "raise shear_flow.numerics.cells_per_radius or lower "
                       "shear_flow.numerics.target_reynolds_number");
        return;
      }
      if (moved.lo[1] < wall_margin || moved.hi[1] > fluid.ny() - wall_margin) {
        fail(step, "the cell reached the wall region (extent in y " + num(moved.lo[1] * dx) + " .. " +
                       num(moved.hi[1] * dx) + " m, walls at 0 and " + num(setup.box_m[1]) +
                       " m); enlarge shear_flow.numerics.box_y_radii or lower the capillary number");
        return;
      }
      if (moved.hi[0] - moved.lo[0] > fluid.nx() - width || moved.hi[2] - moved.lo[2] > fluid.nz() - width) {
        fail(step, "the cell is longer than the periodic box (extent " +
                       num((moved.hi[0] - moved.lo[0]) * dx) + " m in x, " +
                       num((moved.hi[2] - moved.lo[2]) * dx) +
                       " m in z); enlarge shear_flow.numerics.box_x_radii / box_z_radii");
        return;
      }
    }

    if (step % sample_steps == 0) {
      const auto ts = Clock::now();
      const ShearFlowSample s = take_sample(run, result, step);
      result.observables_s += seconds_since(ts);
      if (!std::isfinite(s.taylor_deformation) || !(s.volume_m3 > 0.0)) {
        fail(step, "non-finite shape or non-positive volume");
        return;
      }
      run.last_good_x_lb = cell.positions_lattice;
      if (cb.on_sample) cb.on_sample(s);
      if (cb.on_progress)
        cb.on_progress(std::min(1.0, static_cast<double>(step) / static_cast<double>(max_steps)));
      if (is_steady(result, n)) {
        result.stop = ShearFlowStop::kSteady;
        break;
      }
    }
    if (snapshot_steps > 0 && step % snapshot_steps == 0) {
      run.snapshot_index++;
      const double time_s = run.plan.units.time_to_si(static_cast<double>(step));
      emit_positions(run, time_s, cell.positions_lattice);
      emit_fluid<T>(run, fluid, run.snapshot_index, time_s);
    }
    if (cb.should_stop && (step % sample_steps == 0 || step % 256 == 0) && cb.should_stop()) {
      result.stop = ShearFlowStop::kCancelled;
      result.status = Status(StatusCode::kCancelled, "stopped on request at " + where(run, step));
      break;
    }
  }
  result.time_steps = step;
  // A final sample at the stopping step when it fell between samples.
  if (result.samples.back().time_step != step) {
    const ShearFlowSample s = take_sample(run, result, step);
    if (cb.on_sample) cb.on_sample(s);
  }
}

}  // namespace

double default_stiffness_limit(ibm::Kernel kernel) {
  switch (kernel) {
    case ibm::Kernel::kPeskin4:
      return 2.5;
    case ibm::Kernel::kPeskin3:
      return 0.4;
    case ibm::Kernel::kTrilinear:
      return 0.05;
  }
  return 0.05;
}

std::string_view stop_name(ShearFlowStop stop) {
  switch (stop) {
    case ShearFlowStop::kSteady:
      return "steady";
    case ShearFlowStop::kMaxStrain:
      return "max_strain";
    case ShearFlowStop::kMaxTime:
      return "max_time";
    case ShearFlowStop::kCancelled:
      return "cancelled";
    case ShearFlowStop::kFailed:
      return "failed";
  }
  return "unknown";
}

Status validate(const ShearFlowParams& params, std::string_view field_prefix) {
  const std::string prefix(field_prefix);
  const std::string np = prefix + "numerics.";
  std::string message;
  if (Status s = validate(params.cell, prefix + "cell."); !s.ok()) add_violation(message, s.message());
  if (!positive_finite(params.fluid_density_kg_m3)) {
    add_violation(message, prefix + "fluid_density_kg_m3 = " + num(params.fluid_density_kg_m3) +
                               " must be > 0 and finite");
  }
  if (!positive_finite(params.fluid_viscosity_pa_s)) {
    add_violation(message, prefix + "fluid_viscosity_pa_s = " + num(params.fluid_viscosity_pa_s) +
                               " must be > 0 and finite");
  }
  const bool has_rate = params.shear_rate_per_s != 0.0;
  const bool has_ca = params.capillary_number != 0.0;
  if (has_rate && has_ca) {
    add_violation(message,
                  "set only one of " + prefix + "shear_rate_per_s and " + prefix + "capillary_number");
  } else if (!has_rate && !has_ca) {
    add_violation(message,
                  "set one of " + prefix + "shear_rate_per_s (> 0) or " + prefix + "capillary_number (> 0)");
  } else if (has_rate && !positive_finite(params.shear_rate_per_s)) {
    add_violation(message,
                  prefix + "shear_rate_per_s = " + num(params.shear_rate_per_s) + " must be > 0 and finite");
  } else if (has_ca && !positive_finite(params.capillary_number)) {
    add_violation(message,
                  prefix + "capillary_number = " + num(params.capillary_number) + " must be > 0 and finite");
  }

  const ShearFlowNumerics& n = params.numerics;
  const bool cpr_ok = n.cells_per_radius >= 2.0 && n.cells_per_radius <= 64.0;
  if (!cpr_ok) {
    add_violation(message, np + "cells_per_radius = " + num(n.cells_per_radius) + " must lie in [2, 64]");
  }
  auto check_box = [&](const char* name, double value, double minimum, const char* why) {
    if (!(value >= minimum && value <= 1000.0)) {
      add_violation(message, np + name + " = " + num(value) + " must lie in [" + num(minimum) + ", 1000] (" +
                                 why + ")");
    }
  };
  const double min_periodic = cpr_ok ? min_box_periodic_radii(n) : 2.0;
  const double min_wall = cpr_ok ? min_box_wall_radii(n) : 2.0;
  check_box("box_x_radii", n.box_x_radii, min_periodic,
            "the cell diameter 2 plus one kernel width between the cell and its periodic image");
  check_box("box_y_radii", n.box_y_radii, min_wall,
            "the cell diameter 2 plus half a kernel width and one spacing at each wall");
  check_box("box_z_radii", n.box_z_radii, min_periodic,
            "the cell diameter 2 plus one kernel width between the cell and its periodic image");
  if (!(n.relaxation_time > 0.5 && n.relaxation_time <= 3.0)) {
    add_violation(message, np + "relaxation_time = " + num(n.relaxation_time) + " must lie in (0.5, 3]");
  }
  if (!(n.max_mach > 0.0 && n.max_mach <= 0.3)) {
    add_violation(message, np + "max_mach = " + num(n.max_mach) + " must lie in (0, 0.3]");
  }
  if (!(n.target_reynolds_number >= 0.0 && n.target_reynolds_number <= 1.0)) {
    add_violation(message,
                  np + "target_reynolds_number = " + num(n.target_reynolds_number) + " must lie in [0, 1]");
  }
  if (!(n.steady_tolerance >= 0.0 && n.steady_tolerance < 1.0)) {
    add_violation(message, np + "steady_tolerance = " + num(n.steady_tolerance) + " must lie in [0, 1)");
  }
  const bool sample_ok = n.sample_every_strain > 0.0 && n.sample_every_strain <= 1.0;
  if (!sample_ok) {
    // At most 1 strain unit between samples keeps the tank-treading angle
    // increments (gammadot / 2 per unit strain) unambiguous.
    add_violation(message,
                  np + "sample_every_strain = " + num(n.sample_every_strain) + " must lie in (0, 1]");
  }
  if (!(positive_finite(n.steady_window_strain) &&
        (!sample_ok || n.steady_window_strain >= 2.0 * n.sample_every_strain))) {
    add_violation(message, np + "steady_window_strain = " + num(n.steady_window_strain) +
                               " must be finite and at least 2 sample_every_strain = " +
                               num(2.0 * n.sample_every_strain));
  }
  if (!(positive_finite(n.max_strain) && n.max_strain <= 1e4)) {
    add_violation(message, np + "max_strain = " + num(n.max_strain) + " must lie in (0, 1e4]");
  }
  if (!(n.max_time_s >= 0.0 && std::isfinite(n.max_time_s))) {
    add_violation(message,
                  np + "max_time_s = " + num(n.max_time_s) + " must be >= 0 (0: no limit) and finite");
  }
  if (!(n.snapshot_every_strain >= 0.0 && std::isfinite(n.snapshot_every_strain))) {
    add_violation(message,
                  np + "snapshot_every_strain = " + num(n.snapshot_every_strain) + " must be >= 0 (0: none)");
  }
  if (!std::isfinite(n.memory_limit_bytes)) {
    add_violation(message, np + "memory_limit_bytes = " + num(n.memory_limit_bytes) +
                               " must be finite (<= 0: no limit)");
  }
  if (!(n.max_stiffness_ratio >= 0.0 && n.max_stiffness_ratio <= 100.0)) {
    add_violation(message, np + "max_stiffness_ratio = " + num(n.max_stiffness_ratio) +
                               " must lie in [0, 100] (0: default)");
  }
  if (n.threads < 0) add_violation(message, np + "threads = " + std::to_string(n.threads) + " must be >= 0");
  if (message.empty()) return Status::ok_status();
  return invalid_argument(std::move(message));
}

StatusOr<ShearFlowSetup> plan_shear_flow(const ShearFlowParams& params, std::string_view field_prefix) {
  StatusOr<Plan> plan = make_plan(params, field_prefix);
  if (!plan.ok()) return plan.status();
  return plan->setup;
}

ShearFlowResult run_shear_flow(const ShearFlowParams& params, const ShearFlowCallbacks& callbacks) {
  const auto wall_start = std::chrono::steady_clock::now();
  const std::string prefix = "shear_flow.";
  ShearFlowResult result;
  result.stop = ShearFlowStop::kFailed;
  StatusOr<Plan> planned = make_plan(params, prefix);
  if (!planned.ok()) {
    result.status = planned.status();
    return result;
  }
  Run run;
  run.params = &params;
  run.callbacks = &callbacks;
  run.plan = *planned;
  result.setup = run.plan.setup;
  const ShearFlowNumerics& n = params.numerics;
  const units::Units& u = run.plan.units;
  const double radius = params.cell.radius_m;

  // The cell: mesh centred on its volume centroid, and its elastic body.
  StatusOr<cell::CellBody> built =
      cell::build_cell_body(params.cell, n.volumetric, prefix + "cell.", cell::Centring::kVolumeCentroid);
  if (!built.ok()) {
    result.status = built.status();
    return result;
  }
  result.reference_taylor_deformation = built->reference_taylor_deformation;
  run.mesh = std::move(built->mesh);
  run.body = std::move(built->body);
  const std::array<elastic::Material, 2>& materials = built->materials;
  const std::size_t nv = run.mesh.num_vertices();
  const mesh::MeshQuality quality = mesh::mesh_quality(run.mesh);
  result.mesh_spacing_over_dx = quality.mean_edge_length_m / u.dx_m();
  const double mu_max = std::max(shear_modulus(materials[0]), shear_modulus(materials[1]));
  run.energy_limit_j = kEnergyBlowUp * mu_max * quality.volume_m3;

  // Stability of the explicit update: the stiffest vertex mode against the
  // Stokes drag of one lattice spacing, both in lattice units,
  //   S = k_max,lb / (6 pi eta_lb),  k_max,lb = k_max dt^2 / m,  eta_lb = nu_lb (density 1).
  // The update X += U dt relaxes a vertex mode of stiffness k with a mobility
  // of about 1 / (6 pi eta_lb a) per step, a ~ dx; it scales as dt / (eta / mu).
  // Limits per kernel: default_stiffness_limit (calibrated by blow-up runs).
  {
    const double k_max = stiffest_mode(run.body, run.mesh.positions_m, n.threads);
    // k_lb = F_lb / x_lb = force_to_lattice(k_max dx)
    const double k_lb = u.force_to_lattice(k_max * u.dx_m());
    const double drag_lb = 6.0 * kPi * u.kinematic_viscosity_lattice();
    result.stiffness_ratio = k_lb / drag_lb;
    // The calibrated limits hold for per-tet volume terms, whose stiffest modes
    // alternate from vertex to vertex and are smoothed away by the kernel; the
    // nodal average's stiffest modes span a vertex patch and pass through it:
    // with peskin4 they blew up at ratio 1.96 (Ca = 0.001, 4 cells per radius,
    // 1000 vertices) and ran at 0.98. Half the limit for them.
    const double calibrated = default_stiffness_limit(n.ibm_kernel) *
                              (n.volumetric == elastic::VolumetricTerm::kNodalAverage ? 0.5 : 1.0);
    const double limit = n.max_stiffness_ratio > 0.0 ? n.max_stiffness_ratio : calibrated;
    if (!(result.stiffness_ratio <= limit)) {
      result.status = invalid_argument(
          "the explicit elastic update would be unstable: stiffest vertex mode k_max / (6 pi eta dx) = " +
          num(result.stiffness_ratio) + " (lattice units) exceeds the limit " + num(limit) + " of " +
          std::string(ibm::kernel_name(n.ibm_kernel)) + " (" + prefix +
          "numerics.max_stiffness_ratio; Ca = " + num(result.setup.capillary_number) +
          "). The ratio scales as dt / (eta / mu): lower " + prefix +
          "numerics.target_reynolds_number (now " + num(n.target_reynolds_number) + ") or " + prefix +
          "numerics.relaxation_time (now " + num(n.relaxation_time) + "), raise " + prefix +
          "numerics.cells_per_radius (now " + num(n.cells_per_radius) + ")" +
          (n.ibm_kernel == ibm::Kernel::kPeskin4
               ? std::string()
               : ", or use " + prefix + "numerics.ibm_kernel = peskin4 (the most stable)"));
      return result;
    }
  }
  if (callbacks.on_mesh) callbacks.on_mesh(run.mesh);

  // The fluid: walls at y = 0 and H moving at -u_wall and +u_wall.
  const ShearFlowSetup& setup = run.plan.setup;
  const double u_wall_lb = u.velocity_to_lattice(setup.wall_speed_m_per_s);
  lb::FluidParams fp;
  fp.nx = setup.nx;
  fp.ny = setup.ny;
  fp.nz = setup.nz;
  fp.tau = n.relaxation_time;
  fp.walls_y = true;
  fp.lower_wall_velocity = {-u_wall_lb, 0.0, 0.0};
  fp.upper_wall_velocity = {u_wall_lb, 0.0, 0.0};
  fp.force_field = true;
  fp.velocity_field = true;
  fp.precision = n.single_precision ? lb::Precision::kFloat : lb::Precision::kDouble;
  fp.threads = n.threads;
  StatusOr<lb::Fluid> fluid = lb::make_fluid(fp);
  if (!fluid.ok()) {
    result.status = Status(fluid.status().code(), prefix + "numerics: " + fluid.status().message());
    return result;
  }
  {
    // Steady plane Couette profile u_x(y) = u_wall (2 y / H - 1), nodes at y = j + 1/2.
    const std::size_t nodes = fluid->num_nodes();
    std::vector<double> ux(nodes, 0.0), zero(nodes, 0.0);
    for (int k = 0; k < setup.nz; ++k) {
      for (int j = 0; j < setup.ny; ++j) {
        const double velocity = u_wall_lb * (2.0 * (j + 0.5) / setup.ny - 1.0);
        for (int i = 0; i < setup.nx; ++i) ux[fluid->node(i, j, k)] = velocity;
      }
    }
    lb::set_equilibrium(*fluid, {}, ux, zero, zero);
    lb::update_velocity_field(*fluid);
  }

  // Vertices at the box centre (lattice units).
  const double centre[3] = {0.5 * setup.nx, 0.5 * setup.ny, 0.5 * setup.nz};
  coupling::add_cell(run.cells, run.mesh, run.body, u, centre);
  run.x_si.resize(3 * nv);
  for (std::size_t v = 0; v < nv; ++v) {
    if (run.mesh.on_surface[v] && std::abs(run.mesh.positions_m[3 * v + 2]) < kTankTreadBand * radius) {
      run.tank_vertices.push_back(static_cast<int>(v));
    }
  }
  run.tank_angle.assign(run.tank_vertices.size(), 0.0);
  run.tank_unwrapped.assign(run.tank_vertices.size(), 0.0);

  if (n.single_precision) {
    time_loop<float>(run, *fluid, result);
  } else {
    time_loop<double>(run, *fluid, result);
  }
  summarise(run, result);
  result.wall_time_s = seconds_since(wall_start);
  return result;
}

double small_ca_taylor_deformation(double capillary_number) {
  // D = (5/4) Ca   (Roscoe 1967, small-Ca limit; shared/validation/README.md)
  return 1.25 * capillary_number;
}

double small_ca_inclination_deg_lambda1(double capillary_number) {
  // theta = pi/4 - (5/4) Ca for lambda = 1   (Roscoe 1967, small-Ca limit)
  return (kPi / 4.0 - 1.25 * capillary_number) * 180.0 / kPi;
}

}  // namespace cellflow::scenes
