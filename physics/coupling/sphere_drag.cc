#include "physics/coupling/sphere_drag.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "physics/lb/fluid.h"

namespace cellflow::coupling {

namespace {

// K(x) = 1 - 2.8373 x + 4.19 x^3 - 27.4 x^6 (Hasimoto 1959, a simple cubic array, x = a / L).
double hasimoto_factor(double x) {
  const double x3 = x * x * x;
  return 1.0 - 2.8373 * x + 4.19 * x3 - 27.4 * x3 * x3;
}

}  // namespace

// a / K(a/L) = F / (6 pi eta U)   (Hasimoto's drag law, shared/validation/README.md)
double hasimoto_radius(double drag, double viscosity, double mean_velocity, double box) {
  const double target = drag / (6.0 * std::numbers::pi * viscosity * mean_velocity);
  if (!(target > 0.0) || !std::isfinite(target) || !(box > 0.0)) return std::nan("");
  // a / K(a/L) increases monotonically on (0, 0.4 L): bisection.
  double lo = 0.0, hi = 0.4 * box;
  if (hi / hasimoto_factor(hi / box) < target) return std::nan("");
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (mid / hasimoto_factor(mid / box) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

StatusOr<SphereDragResult> measure_sphere_drag(std::span<const double> points, const SphereDragOptions& o) {
  if (points.empty() || points.size() % 3 != 0) {
    return invalid_argument("sphere_drag: points must hold 3 values per point, at least one point");
  }
  if (!(o.box_nodes >= 8 && o.box_nodes <= 256))
    return invalid_argument("sphere_drag: box_nodes in [8, 256]");
  if (!(o.relaxation_time > 0.5 && o.relaxation_time <= 3.0)) {
    return invalid_argument("sphere_drag: relaxation_time in (0.5, 3]");
  }
  if (!(o.mean_velocity > 0.0 && o.mean_velocity <= 0.01)) {
    return invalid_argument("sphere_drag: mean_velocity in (0, 0.01]");
  }
  if (!(o.tether_stiffness >= 0.0 && o.tether_stiffness <= 10.0)) {
    return invalid_argument("sphere_drag: tether_stiffness in [0, 10]");
  }
  if (!(o.max_steps >= 100 && o.max_steps <= 1000000))
    return invalid_argument("sphere_drag: max_steps in [100, 1e6]");
  const std::size_t n = points.size() / 3;
  const int box = o.box_nodes;
  double extent = 0.0;
  for (const double x : points) {
    if (!std::isfinite(x)) return invalid_argument("sphere_drag: non-finite point coordinate");
    extent = std::max(extent, std::abs(x));
  }
  if (2.0 * extent + 2.0 * ibm::kernel_width(o.kernel) > box) {
    return Status(StatusCode::kFailedPrecondition, "sphere_drag: the body does not fit the box");
  }
  // Solid-sphere estimate of F / U from the cloud's extent, for g and k.
  const double eta = (o.relaxation_time - 0.5) / 3.0;  // rho = 1
  const double resistance = 6.0 * std::numbers::pi * eta * extent / hasimoto_factor(extent / box);
  const double nodes = static_cast<double>(box) * box * box;
  const double g = o.mean_velocity * resistance / nodes;
  const double k =
      o.tether_stiffness > 0.0 ? o.tether_stiffness : resistance / (5.0 * static_cast<double>(n));

  lb::FluidParams fp;
  fp.nx = fp.ny = fp.nz = box;
  fp.tau = o.relaxation_time;
  fp.walls_y = false;
  fp.uniform_force = {g, 0.0, 0.0};
  fp.force_field = true;
  fp.velocity_field = true;
  fp.precision = lb::Precision::kDouble;
  fp.threads = 1;
  StatusOr<lb::Fluid> fluid = lb::make_fluid(fp);
  if (!fluid.ok()) return fluid.status();
  lb::update_velocity_field(*fluid);
  const ibm::Grid grid = ibm::grid_of(*fluid);

  std::vector<double> anchor(points.size()), x(points.size()), f(points.size()), u(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) anchor[i] = x[i] = 0.5 * box + points[i];
  SphereDragResult r;
  r.drag = g * nodes;
  double previous_u = 0.0;
  auto mean_u = [&] {
    const lb::VectorField<const double> v = fluid->velocity_field<double>();
    double sum = 0.0;
    for (std::size_t i = 0; i < fluid->num_nodes(); ++i) sum += v.x[i];
    return sum / nodes;
  };
  for (int step = 1; step <= o.max_steps; ++step) {
    // F_p = -k (X_p - X0_p), spread; collide-stream; X += U dt
    double tether = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      f[i] = -k * (x[i] - anchor[i]);
      if (i % 3 == 0) tether += f[i];
    }
    lb::zero_force_field(*fluid);
    ibm::spread<double>(o.kernel, grid, x, f, fluid->force_field<double>(), 1);
    lb::collide_stream(*fluid);
    ibm::interpolate<double>(o.kernel, grid, fluid->velocity_field<double>(), x, u, 1);
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += u[i];
    r.steps = step;
    r.tether_force = tether;
    if (step % 100 == 0) {
      const double current = mean_u();
      r.mean_velocity = current;
      if (o.on_progress) o.on_progress(step, current, -tether / r.drag);
      if (std::abs(current - previous_u) < o.converged_relative * std::abs(current) &&
          std::abs(tether + r.drag) < 1e-3 * r.drag) {
        r.converged = true;
        break;
      }
      previous_u = current;
    }
  }
  r.hydrodynamic_radius = hasimoto_radius(r.drag, eta, r.mean_velocity, box);
  return r;
}

StatusOr<SphereStressletResult> measure_sphere_stresslet(std::span<const double> points,
                                                         const SphereStressletOptions& o) {
  if (points.empty() || points.size() % 3 != 0) {
    return invalid_argument("sphere_stresslet: points must hold 3 values per point, at least one point");
  }
  for (const int nodes : {o.nx, o.ny, o.nz}) {
    if (!(nodes >= 8 && nodes <= 512)) return invalid_argument("sphere_stresslet: nx, ny, nz in [8, 512]");
  }
  if (!(o.relaxation_time > 0.5 && o.relaxation_time <= 3.0)) {
    return invalid_argument("sphere_stresslet: relaxation_time in (0.5, 3]");
  }
  if (!(o.shear_rate > 0.0 && o.shear_rate <= 1e-3))
    return invalid_argument("sphere_stresslet: shear_rate in (0, 1e-3]");
  if (!(o.steps >= 100 && o.steps <= 1000000))
    return invalid_argument("sphere_stresslet: steps in [100, 1e6]");
  const std::size_t n = points.size() / 3;
  double extent = 0.0, r2 = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!std::isfinite(points[i])) return invalid_argument("sphere_stresslet: non-finite point coordinate");
    extent = std::max(extent, std::abs(points[i]));
    r2 += points[i] * points[i];
  }
  const int w = ibm::kernel_width(o.kernel);
  if (2.0 * extent + 2.0 * w > std::min({o.nx, o.ny, o.nz})) {
    return Status(StatusCode::kFailedPrecondition, "sphere_stresslet: the body does not fit the box");
  }
  const double eta = (o.relaxation_time - 0.5) / 3.0;
  // Tether stiffness: the rotation mode (8 pi eta a^3 against N k <r^2>)
  // relaxes in about five steps.
  const double k = 8.0 * std::numbers::pi * eta * extent * extent * extent / (5.0 * r2);
  const double u_wall = 0.5 * o.shear_rate * o.ny;

  lb::FluidParams fp;
  fp.nx = o.nx;
  fp.ny = o.ny;
  fp.nz = o.nz;
  fp.tau = o.relaxation_time;
  fp.walls_y = true;
  fp.lower_wall_velocity = {-u_wall, 0.0, 0.0};
  fp.upper_wall_velocity = {u_wall, 0.0, 0.0};
  fp.force_field = true;
  fp.velocity_field = true;
  fp.precision = lb::Precision::kDouble;
  fp.threads = 1;
  StatusOr<lb::Fluid> fluid = lb::make_fluid(fp);
  if (!fluid.ok()) return fluid.status();
  {
    // Start in the steady Couette profile u_x = u_wall (2 y / H - 1).
    std::vector<double> ux(fluid->num_nodes(), 0.0), zero(fluid->num_nodes(), 0.0);
    for (int kk = 0; kk < o.nz; ++kk) {
      for (int j = 0; j < o.ny; ++j) {
        for (int i = 0; i < o.nx; ++i) ux[fluid->node(i, j, kk)] = u_wall * (2.0 * (j + 0.5) / o.ny - 1.0);
      }
    }
    lb::set_equilibrium(*fluid, {}, ux, zero, zero);
  }
  lb::update_velocity_field(*fluid);
  const ibm::Grid grid = ibm::grid_of(*fluid);
  const double centre[3] = {0.5 * o.nx, 0.5 * o.ny, 0.5 * o.nz};
  std::vector<double> anchor(points.size()), x(points.size()), f(points.size()), u(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) anchor[i] = x[i] = centre[i % 3] + points[i];
  SphereStressletResult r;
  auto radius_of = [&](double s) {
    return std::cbrt(3.0 * s / (10.0 * std::numbers::pi * eta * o.shear_rate));
  };
  for (int step = 1; step <= o.steps; ++step) {
    double s_xy = 0.0, t_z = 0.0;
    // Anchor angle -gammadot t / 2 (clockwise, the sense of u_x = gammadot y).
    const double angle = o.rotating ? -0.5 * o.shear_rate * (step - 1) : 0.0;
    const double ca = std::cos(angle), sa = std::sin(angle);
    for (std::size_t p = 0; p < n; ++p) {
      const double ax = anchor[3 * p] - centre[0], ay = anchor[3 * p + 1] - centre[1];
      const double target[3] = {centre[0] + ca * ax - sa * ay, centre[1] + sa * ax + ca * ay,
                                anchor[3 * p + 2]};
      for (int d = 0; d < 3; ++d) f[3 * p + d] = -k * (x[3 * p + d] - target[d]);
      const double rx = x[3 * p] - centre[0], ry = x[3 * p + 1] - centre[1];
      // S_xy = -(1/2) sum (f_x y + f_y x) (force on the fluid; a rigid sphere pushes against the strain)
      s_xy -= 0.5 * (f[3 * p] * ry + f[3 * p + 1] * rx);
      t_z += rx * f[3 * p + 1] - ry * f[3 * p];
    }
    lb::zero_force_field(*fluid);
    ibm::spread<double>(o.kernel, grid, x, f, fluid->force_field<double>(), 1);
    lb::collide_stream(*fluid);
    ibm::interpolate<double>(o.kernel, grid, fluid->velocity_field<double>(), x, u, 1);
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += u[i];
    r.steps = step;
    r.stresslet_xy = s_xy;
    r.torque_z = t_z;
    if (o.on_progress && step % 1000 == 0) o.on_progress(step, radius_of(s_xy));
  }
  r.stresslet_radius = radius_of(r.stresslet_xy);
  // A non-rotating sphere in shear feels the torque 8 pi eta a^3 (gammadot / 2).
  r.rotlet_radius = std::cbrt(std::abs(r.torque_z) / (4.0 * std::numbers::pi * eta * o.shear_rate));
  return r;
}

}  // namespace cellflow::coupling
