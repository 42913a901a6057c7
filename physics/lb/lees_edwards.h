// Lees-Edwards boundaries in y for the D3Q19 fluid (unbounded simple shear
// in a periodic box, without walls): the periodic images of the box above
// and below move along x at +U and -U relative to it and are displaced by
// +-Delta(t), Delta = U t. A population that crosses the plane y = ny (or
// y = 0) re-enters at the other side shifted in x by -Delta (+Delta), with
// linear interpolation between the two nearest nodes (mass conserving on the
// periodic row), and carries the image's velocity: the equilibrium part of
// its source node is moved by -U (+U),
//   f_q -> f_q + f_eq_q(rho, u -+ U e_x) - f_eq_q(rho, u)
// (Wagner & Pagonabarraga 2002, J. Stat. Phys. 107, 521). Away from
// the plane the lattice is the periodic one of physics/lb/fluid.h. The
// steady state of an empty box is the linear profile
// u_x = (U / ny) (y - ny / 2) with shear stress rho nu U / ny.
//
// Use: a fluid with walls_y = false; each step calls
// LeesEdwards::collide_stream(fluid) instead of lb::collide_stream(fluid)
// (force field, velocity field, AA or two-array, float or double as there).
// The offset is a function of the time step alone (Delta = U t, t the
// fluid's step count), so a checkpoint of the fluid needs nothing more.
#pragma once

#include <cstdint>
#include <vector>

#include "physics/core/status.h"
#include "physics/lb/fluid.h"

namespace cellflow::lb {

class LeesEdwards {
 public:
  // image_velocity U (lattice units, finite, |U| <= 0.5): the x velocity of
  // the image above the box relative to the box, gammadot ny. The fluid
  // must be periodic in y (walls_y = false) with ny >= 2.
  static StatusOr<LeesEdwards> make(const Fluid& fluid, double image_velocity);

  double image_velocity() const { return image_velocity_; }
  // Delta(t) = U t modulo nx, in [0, nx): the x offset of the image above.
  double offset(std::int64_t time_step) const;

  // One step: the moments of the two layers next to the plane (what the
  // equilibrium shift needs), lb::collide_stream, then the populations
  // that crossed the plane in this step re-mapped as above.
  void collide_stream(Fluid& fluid);

 private:
  LeesEdwards(int nx, int nz, double image_velocity);
  template <class T>
  void layer_moments(const Fluid& fluid);
  template <class T>
  void remap_crossing(Fluid& fluid);

  int nx_ = 0, nz_ = 0;
  double image_velocity_ = 0.0;
  // rho and u of layer y = 0 (first nx nz values) and y = ny - 1 (next nx
  // nz), x innermost, at the time of the step's collision.
  std::vector<double> rho_, ux_, uy_, uz_;
  std::vector<double> row_;  // one shifted row (nx)
};

}  // namespace cellflow::lb
