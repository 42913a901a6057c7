// Lees-Edwards boundaries in y (physics/lb/lees_edwards.h): the empty box
// reaches the unbounded simple shear u_x = (U / ny) (y - ny / 2) with the
// viscous stress rho nu U / ny at every layer, including the two next to the
// plane; mass is kept exactly; a uniform velocity added to the start state
// rides along unchanged (Galilean invariance of the shifted images); a
// density bump crossing the plane arrives shifted by -+Delta = -+U t.
#include "physics/lb/lees_edwards.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "physics/lb/fluid.h"
#include "tests/lb/lb_test_support.h"

namespace cellflow::lb {
namespace {

using testing::make_or_die;

FluidParams periodic_box(int nx, int ny, int nz, double tau, Precision precision, Streaming streaming) {
  FluidParams p;
  p.nx = nx;
  p.ny = ny;
  p.nz = nz;
  p.tau = tau;
  p.walls_y = false;
  p.precision = precision;
  p.streaming = streaming;
  return p;
}

LeesEdwards make_le(const Fluid& fluid, double image_velocity) {
  StatusOr<LeesEdwards> le = LeesEdwards::make(fluid, image_velocity);
  EXPECT_TRUE(le.ok()) << le.status().to_string();
  return std::move(le).value();
}

void set_uniform(Fluid& fluid, double ux) {
  const std::size_t n = fluid.num_nodes();
  std::vector<double> vx(n, ux), zero(n, 0.0);
  set_equilibrium(fluid, {}, vx, zero, zero);
}

struct ProfileError {
  double velocity = 0.0;  // max |u - u_exact| / U over nodes and components
  double stress = 0.0;    // max |sigma_xy / (rho nu gammadot) - 1| over nodes
};

// Against u_x = offset + gammadot (y - ny / 2), y = j + 1/2, and the viscous
// stress sigma_xy = -(1 - 1 / (2 tau)) sum_q c_x c_y (f_q - f_eq_q).
ProfileError profile_error(const Fluid& fluid, double image_velocity, double uniform) {
  const double gammadot = image_velocity / fluid.ny();
  const double tau = fluid.params().tau, nu = (tau - 0.5) / 3.0;
  const testing::Velocity v = testing::velocity(fluid);
  ProfileError e;
  for (int k = 0; k < fluid.nz(); ++k)
    for (int j = 0; j < fluid.ny(); ++j)
      for (int i = 0; i < fluid.nx(); ++i) {
        const std::size_t at = fluid.node(i, j, k);
        const double exact = uniform + gammadot * (j + 0.5 - 0.5 * fluid.ny());
        e.velocity = std::max({e.velocity, std::abs(v.ux[at] - exact) / std::abs(image_velocity),
                               std::abs(v.uy[at]) / std::abs(image_velocity),
                               std::abs(v.uz[at]) / std::abs(image_velocity)});
        const std::array<double, kQ> f = populations(fluid, i, j, k);
        double pxy = 0.0;
        for (int q = 0; q < kQ; ++q) pxy += kCx[q] * kCy[q] * f[q];
        // second moment of f_eq: rho c_s^2 delta + rho u u
        const double pxy_neq = pxy - v.density[at] * v.ux[at] * v.uy[at];
        const double sigma = -(1.0 - 0.5 / tau) * pxy_neq;
        e.stress = std::max(e.stress, std::abs(sigma / (v.density[at] * nu * gammadot) - 1.0));
      }
  return e;
}

// From rest to the steady shear: 3000 steps are 70 decay times of the
// slowest mode (rate nu (2 pi / ny)^2, periodic deviations from the line).
TEST(LeesEdwards, EmptyBoxReachesLinearProfileWithItsStress) {
  for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
    for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
      const double image_velocity = 0.04;  // layers next to the plane at Mach 0.035
      Fluid fluid = make_or_die(periodic_box(5, 16, 3, 0.8, precision, streaming));
      LeesEdwards le = make_le(fluid, image_velocity);
      for (int s = 0; s < 3000; ++s) le.collide_stream(fluid);
      const ProfileError e = profile_error(fluid, image_velocity, 0.0);
      // Double: the linear profile is an exact steady state of the TRT
      // lattice and of the shifted images (observed 2.6e-15 of U and 2.0e-14
      // of the stress); float storage: 4.9e-7 and 2.4e-6.
      const bool dbl = precision == Precision::kDouble;
      EXPECT_LT(e.velocity, dbl ? 1e-12 : 2e-6) << "streaming " << static_cast<int>(streaming);
      EXPECT_LT(e.stress, dbl ? 1e-12 : 1e-5) << "streaming " << static_cast<int>(streaming);
    }
  }
}

// Started on the analytic profile it stays there: the plane adds nothing.
TEST(LeesEdwards, LinearProfileIsSteady) {
  const double image_velocity = 0.05;
  Fluid fluid = make_or_die(periodic_box(7, 20, 2, 1.0, Precision::kDouble, Streaming::kAA));
  const std::size_t n = fluid.num_nodes();
  std::vector<double> ux(n), zero(n, 0.0);
  for (int k = 0; k < fluid.nz(); ++k)
    for (int j = 0; j < fluid.ny(); ++j)
      for (int i = 0; i < fluid.nx(); ++i)
        ux[fluid.node(i, j, k)] = image_velocity / fluid.ny() * (j + 0.5 - 0.5 * fluid.ny());
  set_equilibrium(fluid, {}, ux, zero, zero);
  LeesEdwards le = make_le(fluid, image_velocity);
  // The equilibrium start lacks the non-equilibrium stress part, which the
  // first steps build up; after that the profile is steady to round-off.
  for (int s = 0; s < 1500; ++s) le.collide_stream(fluid);
  const ProfileError before = profile_error(fluid, image_velocity, 0.0);
  for (int s = 0; s < 501; ++s) le.collide_stream(fluid);  // odd count: the other AA phase
  const ProfileError after = profile_error(fluid, image_velocity, 0.0);
  // observed 2.8e-16 and 2.4e-15
  EXPECT_LT(before.velocity, 1e-12);
  EXPECT_LT(after.velocity, 1e-12);
  EXPECT_LT(after.stress, 1e-12);
}

// Mass is kept to round-off while the shear develops from rest (the
// equilibrium shift sums to zero over the five crossing directions of a
// node, the interpolation keeps each row's sum); a uniform velocity V added
// to the start state gives V + the same profile, and the mean momentum V.
TEST(LeesEdwards, MassKeptAndGalileanShift) {
  const double image_velocity = 0.04, uniform = 0.03;
  for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
    Fluid fluid = make_or_die(periodic_box(6, 16, 2, 0.9, Precision::kDouble, streaming));
    set_uniform(fluid, uniform);
    LeesEdwards le = make_le(fluid, image_velocity);
    const double mass0 = total_mass(fluid);
    double worst_mass = 0.0;
    for (int s = 0; s < 3000; ++s) {
      le.collide_stream(fluid);
      if (s % 100 == 0) worst_mass = std::max(worst_mass, std::abs(total_mass(fluid) / mass0 - 1.0));
    }
    EXPECT_LT(worst_mass, 1e-14);  // observed 0
    const ProfileError e = profile_error(fluid, image_velocity, uniform);
    // observed 7.1e-14 and 6.7e-15, momentum 2.8e-15 off
    EXPECT_LT(e.velocity, 1e-12);
    EXPECT_LT(e.stress, 1e-12);
    const testing::Velocity v = testing::velocity(fluid);
    double momentum = 0.0, mass = 0.0;
    for (std::size_t i = 0; i < fluid.num_nodes(); ++i) {
      momentum += v.density[i] * v.ux[i];
      mass += v.density[i];
    }
    EXPECT_NEAR(momentum / mass, uniform, 1e-12);
  }
}

// A density bump in the top layer at x0: the mass that crosses y = ny in the
// first step lands in the bottom layer with its centroid at x0 - Delta - U:
// the image below is displaced by -Delta, and the equilibrium shift by -U
// moves (rho - 1) U / 6 of x momentum from the c_x = +1 to the c_x = -1
// crossing direction, a dipole of one spacing. A bump in the bottom layer
// lands at x0 + Delta + U. Delta = U after one step.
TEST(LeesEdwards, CrossingMassIsShiftedByTheOffset) {
  const double image_velocity = 0.3;  // one step: Delta = 0.3 of a spacing
  for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
    for (int from_top = 0; from_top < 2; ++from_top) {
      Fluid fluid = make_or_die(periodic_box(16, 8, 1, 1.0, Precision::kDouble, streaming));
      const std::size_t n = fluid.num_nodes();
      const int x0 = 8, src = from_top ? fluid.ny() - 1 : 0, dst = from_top ? 0 : fluid.ny() - 1;
      std::vector<double> rho(n, 1.0), zero(n, 0.0);
      rho[fluid.node(x0, src, 0)] = 1.01;
      set_equilibrium(fluid, rho, zero, zero, zero);
      LeesEdwards le = make_le(fluid, image_velocity);
      le.collide_stream(fluid);
      EXPECT_DOUBLE_EQ(le.offset(fluid.time_step()), image_velocity);
      const testing::Velocity v = testing::velocity(fluid);
      double excess = 0.0, moment = 0.0;
      for (int i = 0; i < fluid.nx(); ++i) {
        const double d = v.density[fluid.node(i, dst, 0)] - 1.0;
        excess += d;
        moment += d * i;
      }
      // the crossing directions carry (1/18 + 4/36) of the excess 0.01
      EXPECT_NEAR(excess, 0.01 / 6.0, 1e-12);
      const double expected = from_top ? x0 - 2.0 * image_velocity : x0 + 2.0 * image_velocity;
      EXPECT_NEAR(moment / excess, expected, 1e-10) << "from_top " << from_top;
    }
  }
}

TEST(LeesEdwards, RefusesWallsShortBoxesAndFastImages) {
  FluidParams walls = periodic_box(4, 8, 2, 1.0, Precision::kDouble, Streaming::kAA);
  walls.walls_y = true;
  EXPECT_FALSE(LeesEdwards::make(make_or_die(walls), 0.01).ok());
  EXPECT_FALSE(
      LeesEdwards::make(make_or_die(periodic_box(4, 1, 2, 1.0, Precision::kDouble, Streaming::kAA)), 0.01)
          .ok());
  const Fluid fluid = make_or_die(periodic_box(4, 8, 2, 1.0, Precision::kDouble, Streaming::kAA));
  EXPECT_FALSE(LeesEdwards::make(fluid, 0.6).ok());
  EXPECT_FALSE(LeesEdwards::make(fluid, std::nan("")).ok());
  EXPECT_TRUE(LeesEdwards::make(fluid, -0.2).ok());
  const LeesEdwards le = *LeesEdwards::make(fluid, -0.3);
  EXPECT_NEAR(le.offset(5), 4.0 - 1.5, 1e-12);  // -1.5 modulo nx = 4
}

}  // namespace
}  // namespace cellflow::lb
