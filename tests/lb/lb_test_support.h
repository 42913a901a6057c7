// Helpers shared by the lattice Boltzmann tests: build a fluid, read profiles.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "physics/lb/fluid.h"

namespace cellflow::lb::testing {

inline Fluid make_or_die(const FluidParams& params) {
  StatusOr<Fluid> fluid = make_fluid(params);
  EXPECT_TRUE(fluid.ok()) << fluid.status().to_string();
  return std::move(fluid).value();
}

inline void run(Fluid& fluid, int steps) {
  for (int s = 0; s < steps; ++s) collide_stream(fluid);
}

// Per-node velocity components (x innermost).
struct Velocity {
  std::vector<double> density, ux, uy, uz;
};

inline Velocity velocity(const Fluid& fluid) {
  Velocity v;
  const std::size_t n = fluid.num_nodes();
  v.density.resize(n);
  v.ux.resize(n);
  v.uy.resize(n);
  v.uz.resize(n);
  compute_moments(fluid, v.density, v.ux, v.uy, v.uz);
  return v;
}

// u_x averaged over x and z, one value per y layer.
inline std::vector<double> ux_profile(const Fluid& fluid) {
  const Velocity v = velocity(fluid);
  std::vector<double> profile(fluid.ny(), 0.0);
  for (int k = 0; k < fluid.nz(); ++k)
    for (int j = 0; j < fluid.ny(); ++j)
      for (int i = 0; i < fluid.nx(); ++i) profile[j] += v.ux[fluid.node(i, j, k)];
  for (double& u : profile) u /= static_cast<double>(fluid.nx()) * fluid.nz();
  return profile;
}

// Largest |u_x(node) - profile(y)| over all nodes: the flow must stay 1-D.
inline double max_deviation_from_profile(const Fluid& fluid, const std::vector<double>& profile) {
  const Velocity v = velocity(fluid);
  double dev = 0.0;
  for (int k = 0; k < fluid.nz(); ++k)
    for (int j = 0; j < fluid.ny(); ++j)
      for (int i = 0; i < fluid.nx(); ++i) {
        const std::size_t at = fluid.node(i, j, k);
        dev = std::max({dev, std::abs(v.ux[at] - profile[j]), std::abs(v.uy[at]), std::abs(v.uz[at])});
      }
  return dev;
}

}  // namespace cellflow::lb::testing
