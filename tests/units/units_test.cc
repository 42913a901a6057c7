// SI <-> lattice conversion: the defining relations, round trips, and the
// refusals of unstable lattices naming the option to change.
#include "physics/units/units.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "physics/lb/fluid.h"

namespace cellflow::units {
namespace {

// The paper's shear-flow setting (section 7.1): water, a 10 um cell.
LatticeChoice paper_choice() {
  LatticeChoice c;
  c.cell_radius_m = 10e-6;
  c.cells_per_radius = 6.0;
  c.relaxation_time = 1.0;
  c.fluid_density_kg_m3 = 1e3;
  c.fluid_viscosity_pa_s = 1e-3;
  return c;
}

Units make_or_die(const LatticeChoice& c) {
  StatusOr<Units> u = make_units(c);
  EXPECT_TRUE(u.ok()) << u.status().to_string();
  return u.value();
}

TEST(Units, DefiningRelations) {
  const Units u = make_or_die(paper_choice());
  // dx = R / cells_per_radius
  EXPECT_DOUBLE_EQ(u.dx_m(), 10e-6 / 6.0);
  // dt = nu_lb dx^2 / nu with nu_lb = 1/6, nu = 1e-6 m^2/s
  EXPECT_DOUBLE_EQ(u.dt_s(), (1.0 / 6.0) * u.dx_m() * u.dx_m() / 1e-6);
  EXPECT_DOUBLE_EQ(u.kinematic_viscosity_lattice(), 1.0 / 6.0);
  // the SI viscosity maps onto the lattice viscosity and the density onto 1
  EXPECT_NEAR(u.kinematic_viscosity_to_lattice(1e-6), 1.0 / 6.0, 1e-15);
  EXPECT_NEAR(u.density_to_lattice(1e3), 1.0, 1e-15);
  // dynamic viscosity eta_lb = rho_lb nu_lb: stress = eta gammadot is consistent
  const double gammadot = 4.0;  // 1/s
  const double stress_si = 1e-3 * gammadot;
  EXPECT_NEAR(u.stress_to_lattice(stress_si), (1.0 / 6.0) * u.shear_rate_to_lattice(gammadot),
              1e-14 * u.stress_to_lattice(stress_si));
  // force density = force / volume
  const double force_n = 3e-12;
  EXPECT_NEAR(u.force_density_to_lattice(force_n / std::pow(u.dx_m(), 3)), u.force_to_lattice(force_n),
              1e-14 * u.force_to_lattice(force_n));
}

TEST(Units, RoundTripsSiLatticeSi) {
  const Units u = make_or_die(paper_choice());
  const double rel = 1e-15;
  EXPECT_NEAR(u.length_to_si(u.length_to_lattice(7.3e-6)), 7.3e-6, rel * 7.3e-6);
  EXPECT_NEAR(u.time_to_si(u.time_to_lattice(2.5)), 2.5, rel * 2.5);
  EXPECT_NEAR(u.velocity_to_si(u.velocity_to_lattice(3e-4)), 3e-4, rel * 3e-4);
  EXPECT_NEAR(u.force_to_si(u.force_to_lattice(4e-9)), 4e-9, rel * 4e-9);
  EXPECT_NEAR(u.force_density_to_si(u.force_density_to_lattice(1.7e3)), 1.7e3, rel * 1.7e3);
  EXPECT_NEAR(u.shear_rate_to_si(u.shear_rate_to_lattice(4.0)), 4.0, rel * 4.0);
  EXPECT_NEAR(u.stress_to_si(u.stress_to_lattice(0.25)), 0.25, rel * 0.25);
  EXPECT_NEAR(u.density_to_si(u.density_to_lattice(1.05e3)), 1.05e3, rel * 1.05e3);
  // and lattice -> SI -> lattice
  EXPECT_NEAR(u.velocity_to_lattice(u.velocity_to_si(0.01)), 0.01, rel * 0.01);
  EXPECT_NEAR(u.force_to_lattice(u.force_to_si(1e-5)), 1e-5, rel * 1e-5);
}

// Dimensional consistency: a velocity is a length over a time, a force a
// mass times a length over a time squared.
TEST(Units, ConversionsAreDimensionallyConsistent) {
  const Units u = make_or_die(paper_choice());
  const double l = 3e-6, t = 1e-3;
  EXPECT_NEAR(u.velocity_to_lattice(l / t), u.length_to_lattice(l) / u.time_to_lattice(t), 1e-15 * l / t);
  const double m = 2e-15;  // kg
  const double f = m * l / (t * t);
  EXPECT_NEAR(u.force_to_lattice(f),
              (m / u.mass_kg()) * u.length_to_lattice(l) / std::pow(u.time_to_lattice(t), 2),
              1e-14 * u.force_to_lattice(f));
}

TEST(Units, RelaxationTimeOutsideRangeNamesOption) {
  LatticeChoice c = paper_choice();
  c.relaxation_time = 0.5;
  StatusOr<Units> u = make_units(c);
  ASSERT_FALSE(u.ok());
  EXPECT_EQ(u.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(u.status().message().find("numerics.relaxation_time"), std::string::npos) << u.status().message();

  c.relaxation_time = 3.5;  // builds, but validate_lattice refuses tau > 3
  const Units big = make_or_die(c);
  const Status s = validate_lattice(big, c, 1e-6);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("numerics.relaxation_time"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("(0.5, 3]"), std::string::npos) << s.message();

  c.relaxation_time = 3.0;  // the upper end is allowed
  EXPECT_TRUE(validate_lattice(make_or_die(c), c, 1e-6).ok());
}

TEST(Units, MachAboveLimitNamesOptionsAndPassingValues) {
  LatticeChoice c = paper_choice();
  const Units u = make_or_die(c);
  // Wall speed giving Ma = 0.2: u_lb = 0.2 c_s.
  const double u_wall = u.velocity_to_si(0.2 / std::sqrt(3.0));
  const Status s = validate_lattice(u, c, u_wall);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("numerics.max_mach"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("numerics.cells_per_radius"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("numerics.relaxation_time"), std::string::npos) << s.message();
  // The suggested values pass: cells_per_radius 6 -> 12, tau 1 -> 0.75.
  EXPECT_NE(s.message().find("at least 12"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("at most 0.75"), std::string::npos) << s.message();
  LatticeChoice finer = c;
  finer.cells_per_radius = 12.0 * (1 + 1e-12);
  EXPECT_TRUE(validate_lattice(make_or_die(finer), finer, u_wall).ok());
  LatticeChoice faster = c;
  faster.relaxation_time = 0.75 * (1 - 1e-12);
  EXPECT_TRUE(validate_lattice(make_or_die(faster), faster, u_wall).ok());
  // Just below the limit passes; a looser limit passes too.
  EXPECT_TRUE(validate_lattice(u, c, 0.99 * 0.5 * u_wall).ok());
  EXPECT_TRUE(validate_lattice(u, c, u_wall, {.max_mach = 0.25}).ok());
  // The limit itself is validated.
  EXPECT_NE(validate_lattice(u, c, u_wall, {.max_mach = 0.0}).message().find("numerics.max_mach"),
            std::string::npos);
}

TEST(Units, PaperSettingIsFarBelowMachLimit) {
  // gammadot = 4/s, H = 15 R: u_wall = H gammadot / 2 = 3e-4 m/s.
  const LatticeChoice c = paper_choice();
  const Units u = make_or_die(c);
  EXPECT_TRUE(validate_lattice(u, c, 3e-4).ok());
  EXPECT_LT(u.velocity_to_lattice(3e-4) * std::sqrt(3.0), 1e-3);
}

TEST(Units, OtherFieldsValidated) {
  LatticeChoice c = paper_choice();
  c.cells_per_radius = 0.0;
  EXPECT_NE(make_units(c).status().message().find("numerics.cells_per_radius"), std::string::npos);
  c = paper_choice();
  c.fluid_viscosity_pa_s = -1.0;
  EXPECT_NE(make_units(c).status().message().find("fluid_viscosity_pa_s"), std::string::npos);
  c = paper_choice();
  c.cell_radius_m = 0.0;
  EXPECT_FALSE(make_units(c).ok());
  c = paper_choice();
  StatusOr<Units> prefixed =
      make_units({.cell_radius_m = 1e-5, .cells_per_radius = -1.0}, "shear_flow.numerics.");
  EXPECT_NE(prefixed.status().message().find("shear_flow.numerics.cells_per_radius"), std::string::npos);
}

TEST(Units, NodesAlongAndMemoryEstimate) {
  const Units u = make_or_die(paper_choice());
  // The paper's box 10 x 15 x 5 radii at 6 cells per radius.
  EXPECT_EQ(nodes_along(u, 10 * 10e-6), 60);
  EXPECT_EQ(nodes_along(u, 15 * 10e-6), 90);
  EXPECT_EQ(nodes_along(u, 5 * 10e-6), 30);
  EXPECT_EQ(nodes_along(u, 1e-9), 1);
  // 19 populations + 3 force + 3 velocity arrays of 162000 nodes + 16 padding
  // (physics/lb), plus the AA wall densities of two layers.
  const std::size_t per_array = 60u * 90u * 30u + 16u;
  EXPECT_EQ(estimate_lattice_bytes(60, 90, 30, false), 25u * per_array * 8u + 2u * 60u * 30u * 8u);
  EXPECT_EQ(estimate_lattice_bytes(60, 90, 30, true), 25u * per_array * 4u + 2u * 60u * 30u * 4u);
  const std::size_t bytes = estimate_lattice_bytes(60, 90, 30, false);
  EXPECT_TRUE(check_memory(bytes, 1e9).ok());
  EXPECT_TRUE(check_memory(bytes, 0.0).ok());  // no limit
  const Status s = check_memory(bytes, 1e6);
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted);
  EXPECT_NE(s.message().find("numerics.memory_limit_bytes"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("numerics.cells_per_radius"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace cellflow::units
