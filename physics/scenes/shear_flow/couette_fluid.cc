// The Couette fluid of the flow scenes (see couette_fluid.h).
#include "physics/scenes/shear_flow/couette_fluid.h"

#include <string>
#include <vector>

namespace cellflow::scenes {

StatusOr<lb::Fluid> make_couette_fluid(const ShearFlowSetup& setup, const units::Units& u,
                                       const ShearFlowNumerics& n, std::string_view field_prefix,
                                       const std::vector<double>& phase_taus) {
  const double u_wall_lb = u.velocity_to_lattice(setup.wall_speed_m_per_s);
  lb::FluidParams fp;
  fp.nx = setup.nx;
  fp.ny = setup.ny;
  fp.nz = setup.nz;
  fp.tau = n.relaxation_time;
  // Lees-Edwards: periodic in y, the planes (lb::LeesEdwards) shift what crosses.
  fp.walls_y = n.boundaries == ShearFlowBoundaries::kWalls;
  if (fp.walls_y) {
    fp.lower_wall_velocity = {-u_wall_lb, 0.0, 0.0};
    fp.upper_wall_velocity = {u_wall_lb, 0.0, 0.0};
  }
  fp.force_field = true;
  fp.velocity_field = true;
  fp.precision = n.single_precision ? lb::Precision::kFloat : lb::Precision::kDouble;
  fp.threads = n.threads;
  fp.phase_taus = phase_taus;
  StatusOr<lb::Fluid> fluid = lb::make_fluid(fp);
  if (!fluid.ok()) {
    return Status(fluid.status().code(), std::string(field_prefix) + "numerics: " + fluid.status().message());
  }
  return fluid;
}

void start_couette_profile(lb::Fluid& fluid, double u_wall_lb) {
  {
    // Steady plane Couette profile u_x(y) = u_wall (2 y / H - 1), nodes at y = j + 1/2.
    const std::size_t nodes = fluid.num_nodes();
    std::vector<double> ux(nodes, 0.0), zero(nodes, 0.0);
    const int nx = fluid.nx(), ny = fluid.ny(), nz = fluid.nz();
    for (int k = 0; k < nz; ++k) {
      for (int j = 0; j < ny; ++j) {
        const double velocity = u_wall_lb * (2.0 * (j + 0.5) / ny - 1.0);
        for (int i = 0; i < nx; ++i) ux[fluid.node(i, j, k)] = velocity;
      }
    }
    lb::set_equilibrium(fluid, {}, ux, zero, zero);
  }
  // After the start profile's two per-node buffers are freed: this one holds
  // three of its own (the job's memory estimate counts the larger set, not
  // both; together they overran it by 3 doubles per node, spec fuzzer).
  lb::update_velocity_field(fluid);
}

namespace {

template <class T>
void emit_typed(const lb::Fluid& fluid, const units::Units& units, int index, double time_s,
                const std::function<void(const FluidVelocitySnapshot&)>& emit) {
  const lb::VectorField<const T> u = fluid.velocity_field<T>();
  const std::size_t n = fluid.num_nodes();
  const double scale = units.velocity_to_si(1.0);
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
  snap.spacing_m = units.dx_m();
  snap.ux_m_per_s = ux;
  snap.uy_m_per_s = uy;
  snap.uz_m_per_s = uz;
  emit(snap);
}

template <class T>
double wall_shear_rate_typed(const lb::Fluid& fluid, double u_wall_lb) {
  const lb::VectorField<const T> u = fluid.velocity_field<T>();
  const int nx = fluid.nx(), ny = fluid.ny(), nz = fluid.nz();
  double lower = 0.0, upper = 0.0;
  for (int k = 0; k < nz; ++k) {
    for (int i = 0; i < nx; ++i) {
      lower += static_cast<double>(u.x[fluid.node(i, 0, k)]);
      upper += static_cast<double>(u.x[fluid.node(i, ny - 1, k)]);
    }
  }
  const double plane = static_cast<double>(nx) * nz;
  // du/dy at y = 0: (u_0 - (-u_wall)) / (1/2); at y = H: (u_wall - u_top) / (1/2).
  return 0.5 * ((lower / plane + u_wall_lb) / 0.5 + (u_wall_lb - upper / plane) / 0.5);
}

}  // namespace

double couette_wall_shear_rate(const lb::Fluid& fluid, double u_wall_lb) {
  if (fluid.params().precision == lb::Precision::kFloat)
    return wall_shear_rate_typed<float>(fluid, u_wall_lb);
  return wall_shear_rate_typed<double>(fluid, u_wall_lb);
}

void emit_fluid_velocity(const lb::Fluid& fluid, const units::Units& units, int index, double time_s,
                         const std::function<void(const FluidVelocitySnapshot&)>& emit) {
  if (!emit) return;
  if (fluid.params().precision == lb::Precision::kFloat) {
    emit_typed<float>(fluid, units, index, time_s, emit);
  } else {
    emit_typed<double>(fluid, units, index, time_s, emit);
  }
}

}  // namespace cellflow::scenes
