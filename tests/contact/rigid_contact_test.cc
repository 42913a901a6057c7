// Contact kernel: forces are minus the gradient of the contact energy, the
// Hessian blocks are the derivative of the forces (both against central
// finite differences), and each obstacle's reaction is minus the sum of the
// vertex forces it exerts.
#include "physics/contact/rigid_contact.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace cellflow::contact {
namespace {

constexpr double kRadius = 8.6e-6;

// Vertices scattered in a slab around both plates and around the probe so that
// every branch (outside range, inside range, penetrating) is exercised.
struct ContactSetup {
  Obstacles obstacles;
  std::vector<double> positions;
  std::vector<std::int32_t> vertices;
};

ContactSetup make_setup(bool plates, bool probe) {
  ContactSetup s;
  s.obstacles.penalty = {.stiffness_n_per_m = 1e-3, .range_m = 0.05 * kRadius};
  if (plates) {
    s.obstacles.lower_plate_z_m = -kRadius;
    s.obstacles.upper_plate_z_m = kRadius;
  }
  if (probe)
    s.obstacles.probe = Probe{.centre_m = {0.1 * kRadius, -0.2 * kRadius, 0.0}, .radius_m = 0.5 * kRadius};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> lateral(-0.6 * kRadius, 0.6 * kRadius);
  std::uniform_real_distribution<double> offset(-0.04 * kRadius, 0.06 * kRadius);
  const int n = 60;
  for (int i = 0; i < n; ++i) {
    double z;
    double x = lateral(rng), y = lateral(rng);
    if (probe && (!plates || i % 3 == 2)) {
      // on a shell around the probe surface
      const double theta = std::acos(1.0 - 2.0 * (i + 0.5) / n), phi = 2.4 * i;
      const double rad = s.obstacles.probe->radius_m + offset(rng);
      x = s.obstacles.probe->centre_m[0] + rad * std::sin(theta) * std::cos(phi);
      y = s.obstacles.probe->centre_m[1] + rad * std::sin(theta) * std::sin(phi);
      z = s.obstacles.probe->centre_m[2] + rad * std::cos(theta);
    } else {
      z = (i % 2 == 0) ? -kRadius + offset(rng) : kRadius - offset(rng);
    }
    s.positions.insert(s.positions.end(), {x, y, z});
  }
  // every second vertex is a contact vertex (the others must feel nothing)
  for (int i = 0; i < n; i += 2) s.vertices.push_back(i);
  for (int i = 1; i < n; i += 4) s.vertices.push_back(i);
  return s;
}

class ContactKernel : public ::testing::TestWithParam<std::pair<bool, bool>> {};

TEST_P(ContactKernel, ForcesAreMinusEnergyGradient) {
  ContactSetup s = make_setup(GetParam().first, GetParam().second);
  std::vector<double> forces(s.positions.size(), 0.0);
  const ContactEvaluation eval =
      add_contact_forces(s.obstacles, s.vertices, s.positions.data(), forces.data());
  ASSERT_GT(eval.num_active, 5);
  ASSERT_GT(eval.max_penetration_m, 0.0);
  const double h = 1e-6 * s.obstacles.penalty.range_m;
  double max_force = 0.0;
  for (double f : forces) max_force = std::max(max_force, std::abs(f));
  ASSERT_GT(max_force, 0.0);
  for (std::size_t i = 0; i < s.positions.size(); ++i) {
    std::vector<double> y = s.positions;
    y[i] += h;
    const double ep = contact_energy(s.obstacles, s.vertices, y.data()).energy_j;
    y[i] -= 2 * h;
    const double em = contact_energy(s.obstacles, s.vertices, y.data()).energy_j;
    const double fd_force = -(ep - em) / (2 * h);
    // central differences of a cubic: error ~ h^2 phi''' ~ 1e-12 of the force scale
    EXPECT_NEAR(forces[i], fd_force, 1e-6 * max_force) << "dof " << i;
  }
  // energy of the force pass equals the energy-only pass bit for bit
  EXPECT_EQ(eval.energy_j, contact_energy(s.obstacles, s.vertices, s.positions.data()).energy_j);
}

TEST_P(ContactKernel, HessianIsDerivativeOfForces) {
  ContactSetup s = make_setup(GetParam().first, GetParam().second);
  std::vector<double> blocks(9 * s.vertices.size(), 0.0);
  add_contact_hessian_blocks(s.obstacles, s.vertices, s.positions.data(), blocks.data());
  double max_entry = 0.0;
  for (double b : blocks) max_entry = std::max(max_entry, std::abs(b));
  ASSERT_GT(max_entry, 0.0);
  const double h = 1e-6 * s.obstacles.penalty.range_m;
  for (std::size_t k = 0; k < s.vertices.size(); ++k) {
    const std::size_t v = static_cast<std::size_t>(s.vertices[k]);
    for (int b = 0; b < 3; ++b) {
      std::vector<double> y = s.positions, fp(y.size(), 0.0), fm(y.size(), 0.0);
      y[3 * v + b] += h;
      add_contact_forces(s.obstacles, s.vertices, y.data(), fp.data());
      y[3 * v + b] -= 2 * h;
      add_contact_forces(s.obstacles, s.vertices, y.data(), fm.data());
      for (int a = 0; a < 3; ++a) {
        // K_ab = d^2E/dy_a dy_b = -d f_a / d y_b
        const double fd = -(fp[3 * v + a] - fm[3 * v + a]) / (2 * h);
        EXPECT_NEAR(blocks[9 * k + 3 * a + b], fd, 1e-6 * max_entry) << "vertex " << v << " " << a << b;
      }
      // no coupling to other vertices
      for (std::size_t i = 0; i < y.size(); ++i) {
        if (i / 3 == v) continue;
        EXPECT_EQ(fp[i], fm[i]);
      }
    }
  }
}

TEST_P(ContactKernel, ReactionIsMinusSumOfVertexForces) {
  ContactSetup s = make_setup(GetParam().first, GetParam().second);
  std::vector<double> forces(s.positions.size(), 0.0);
  const ContactEvaluation eval =
      add_contact_forces(s.obstacles, s.vertices, s.positions.data(), forces.data());
  double sum[3] = {0, 0, 0};
  double scale = 0.0;
  for (std::size_t i = 0; i < forces.size(); ++i) {
    sum[i % 3] += forces[i];
    scale += std::abs(forces[i]);
  }
  const double total_reaction_z =
      eval.lower_plate_reaction_n + eval.upper_plate_reaction_n + eval.probe_reaction_n[2];
  EXPECT_NEAR(total_reaction_z, -sum[2], 1e-12 * scale);
  EXPECT_NEAR(eval.probe_reaction_n[0], -sum[0], 1e-12 * scale);
  EXPECT_NEAR(eval.probe_reaction_n[1], -sum[1], 1e-12 * scale);
  // each obstacle alone: its reaction is minus the forces it exerts
  if (s.obstacles.upper_plate_z_m) {
    Obstacles upper_only;
    upper_only.penalty = s.obstacles.penalty;
    upper_only.upper_plate_z_m = s.obstacles.upper_plate_z_m;
    std::vector<double> fu(forces.size(), 0.0);
    add_contact_forces(upper_only, s.vertices, s.positions.data(), fu.data());
    double sum_z = 0.0;
    for (std::size_t i = 2; i < fu.size(); i += 3) sum_z += fu[i];
    EXPECT_GT(eval.upper_plate_reaction_n, 0.0);
    EXPECT_NEAR(eval.upper_plate_reaction_n, -sum_z, 1e-12 * scale);
    EXPECT_LT(eval.lower_plate_reaction_n, 0.0);
  }
}

INSTANTIATE_TEST_SUITE_P(Obstacles, ContactKernel,
                         ::testing::Values(std::make_pair(true, false), std::make_pair(false, true),
                                           std::make_pair(true, true)));

TEST(ContactPenalty, LawAtKnownGaps) {
  Obstacles o;
  o.penalty = {.stiffness_n_per_m = 2.0, .range_m = 0.1};
  o.lower_plate_z_m = 0.0;
  const std::int32_t vertex = 0;
  // gap = r: no force; gap = r/2: k r / 4, energy k r^2 / 24; gap = 0: force k r, energy k r^2 / 3;
  // gap = -r: force 3 k r, energy k (4 r^2 - 2 r^2 + r^2 / 3) = 7/3 k r^2
  for (auto [z, force, energy] :
       {std::tuple{0.1, 0.0, 0.0}, std::tuple{0.05, 0.05, 2.0 * 0.01 / 24.0},
        std::tuple{0.0, 0.2, 2.0 * 0.01 / 3.0}, std::tuple{-0.1, 0.6, 7.0 / 3.0 * 2.0 * 0.01}}) {
    double y[3] = {0.0, 0.0, z}, f[3] = {0, 0, 0};
    const ContactEvaluation e = add_contact_forces(o, std::span(&vertex, 1), y, f);
    EXPECT_NEAR(f[2], force, 1e-15);
    EXPECT_NEAR(e.energy_j, energy, 1e-15);
    EXPECT_NEAR(e.max_penetration_m, std::max(0.0, -z), 1e-15);
  }
}

TEST(ContactPenalty, DefaultsBoundPenetrationAtTheDesignForce) {
  const double E = 150.0, h = 0.13 * kRadius;
  const PenaltyParams p = default_penalty(E, kRadius, h);
  EXPECT_NEAR(p.range_m, 5e-3 * kRadius, 1e-20);
  // the design force (20 E h^2) on one vertex penetrates a plate by 1e-3 R
  Obstacles o;
  o.penalty = p;
  o.lower_plate_z_m = 0.0;
  const std::int32_t vertex = 0;
  const double design_force = 20.0 * E * h * h;
  // bisection for the height where the plate force equals the design force
  double lo = -0.1 * kRadius, hi = 0.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    double y[3] = {0, 0, mid}, f[3] = {0, 0, 0};
    add_contact_forces(o, std::span(&vertex, 1), y, f);
    (f[2] > design_force ? lo : hi) = mid;
  }
  double y[3] = {0, 0, lo}, f[3] = {0, 0, 0};
  EXPECT_NEAR(add_contact_forces(o, std::span(&vertex, 1), y, f).max_penetration_m, 1e-3 * kRadius,
              1e-9 * kRadius);
}

}  // namespace
}  // namespace cellflow::contact
