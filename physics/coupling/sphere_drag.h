// Hydrodynamic radius of an immersed-boundary point cloud, from its Stokes
// drag in a periodic lattice: what justifies the shear-flow scene's
// hydrodynamic radius correction (ShearFlowNumerics.hydrodynamic_radius_offset).
//
// Every point is tethered to its reference position by a spring
// F_p = -k (X_p - X0_p) (a rigid body up to the small spring displacement);
// a uniform body force g drives the fluid through the periodic box (a simple
// cubic array of the body, side L). In the steady state the tethers hold the
// total force g N; Hasimoto's drag law of a cubic array (shared/validation)
//   F = 6 pi eta a U / (1 - 2.8373 a/L + 4.19 (a/L)^3 - 27.4 (a/L)^6),
// U the mean velocity over the whole box, is solved for the radius a: the
// radius of the solid sphere with the same drag. For a point cloud on a
// sphere of radius R it exceeds R by a fraction of the lattice spacing that
// depends on the kernel (the fluid within the kernel's reach moves with the
// points).
//
// Lattice units throughout (dx = dt = 1, rho = 1).
#pragma once

#include <functional>
#include <span>

#include "physics/core/status.h"
#include "physics/ibm/ibm.h"

namespace cellflow::coupling {

struct SphereDragOptions {
  int box_nodes = 32;            // L, periodic in x, y, z; in [8, 256]
  double relaxation_time = 1.0;  // LB tau in (0.5, 3]
  ibm::Kernel kernel = ibm::Kernel::kPeskin4;
  // Target mean velocity (sets g from the solid-sphere estimate); in (0, 0.01].
  double mean_velocity = 1e-3;
  // Tether stiffness per point, lattice units. The rigid-body mode relaxes in
  // about (F/U) / (N k) steps, which must stay well above 1 for the explicit
  // update: 0 picks (F/U) / (5 N) (five steps) from the solid-sphere estimate.
  double tether_stiffness = 0.0;
  int max_steps = 20000;             // in [100, 10^6]
  double converged_relative = 1e-6;  // stop when U changes less than this over 100 steps
  // Called every 100 steps with (step, U, tether force / drag), e.g. to print convergence.
  std::function<void(int, double, double)> on_progress;
};

struct SphereDragResult {
  double drag = 0.0;                 // g N, lattice units
  double tether_force = 0.0;         // sum of the tether forces along x (-> -drag when steady)
  double mean_velocity = 0.0;        // U, mean x velocity over all nodes
  double hydrodynamic_radius = 0.0;  // a of Hasimoto's law, lattice spacings
  int steps = 0;
  bool converged = false;
};

// `points`: x0 y0 z0 x1 ... in lattice units about the body's own centre
// (the body is placed at the box centre). kInvalidArgument for options out
// of range or an empty/odd point list; kFailedPrecondition if the body does
// not fit the box with a kernel width to spare.
StatusOr<SphereDragResult> measure_sphere_drag(std::span<const double> points,
                                               const SphereDragOptions& options = {});

// The stresslet radius: the same tethered cloud at the centre of a plane
// Couette flow (walls at y = 0 and ny moving at -+u_wall, periodic in x and
// z). A rigid sphere resists the strain with the stresslet
//   S_xy = (20/3) pi eta a^3 E_xy,  E_xy = gammadot / 2   (Batchelor 1970),
// measured as -(1/2) sum_p (f_x y + f_y x) of the forces the points exert on
// the fluid. This, not the drag, sets the deformation of a cell in shear
// (the fluid pulls on the cell through its stresslet), so it is the radius
// the flow scene corrects. Walls and periodic images enlarge S by a few
// per cent (O((a / d)^3)); measure at two resolutions in the same box (in
// radii) to separate that from the lattice offset.
struct SphereStressletOptions {
  int nx = 60, ny = 90, nz = 30;  // nodes, each in [8, 512]
  double relaxation_time = 1.0;   // LB tau in (0.5, 3]
  ibm::Kernel kernel = ibm::Kernel::kPeskin4;
  double shear_rate = 1e-4;  // gammadot in lattice units, (0, 1e-3]
  int steps = 10000;         // in [100, 10^6]
  // The anchors rotate with the shear's vorticity, -gammadot / 2 about z (a
  // freely rotating sphere, as the cell tank-treads); false: held still.
  bool rotating = true;
  std::function<void(int, double)> on_progress;  // every 1000 steps: (step, a)
};

struct SphereStressletResult {
  double stresslet_xy = 0.0;      // S_xy, lattice units
  double stresslet_radius = 0.0;  // a = (3 S_xy / (10 pi eta gammadot))^(1/3), lattice spacings
  double torque_z = 0.0;          // sum (x f_y - y f_x), the tethers' hold against rotation
  double rotlet_radius = 0.0;     // a from |T_z| = 4 pi eta a^3 gammadot (non-rotating sphere)
  int steps = 0;
};

StatusOr<SphereStressletResult> measure_sphere_stresslet(std::span<const double> points,
                                                         const SphereStressletOptions& options = {});

// Hasimoto's law solved for a: a / K(a / L) = F / (6 pi eta U). NaN if no a
// in (0, 0.4 L) fits.
double hasimoto_radius(double drag, double viscosity, double mean_velocity, double box);

}  // namespace cellflow::coupling
