// The immersed-boundary coupling of the shear-flow scene
// (physics/coupling/immersed_cell.h): a force-free cell in a fluid at
// rest stays at rest; spreading the elastic forces of a deformed cell puts
// exactly their total force and torque into the fluid; the local clearing of
// the force field leaves no stale force behind. Two cells: the elastic forces
// and the spread are those of each cell alone (spreading is linear), the
// clearing covers the previous supports of both, and each cell is advected
// by its own interpolated velocity.
#include "physics/coupling/immersed_cell.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <utility>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/lb/fluid.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/units/units.h"

namespace cellflow::coupling {
namespace {

constexpr double kRadius = 6e-6;  // m
constexpr int kBox = 24;          // lattice nodes per direction

units::Units test_units() {
  units::LatticeChoice choice;
  choice.cell_radius_m = kRadius;
  choice.cells_per_radius = 4.0;
  StatusOr<units::Units> u = units::make_units(choice);
  EXPECT_TRUE(u.ok()) << u.status().to_string();
  return u.value();
}

struct Cell {
  mesh::TetMesh mesh;
  elastic::ElasticBody body;
};

Cell make_cell(int vertices) {
  mesh::SphereMeshOptions options;
  options.radius_m = kRadius;
  options.target_vertex_count = vertices;
  StatusOr<mesh::TetMesh> m = mesh::make_sphere_mesh(options);
  EXPECT_TRUE(m.ok()) << m.status().to_string();
  elastic::Material material;
  material.youngs_modulus_pa = 100.0;
  material.poisson_ratio = 0.48;
  const elastic::Material materials[2] = {material, material};
  StatusOr<elastic::ElasticBody> body = elastic::make_elastic_body(*m, materials);
  EXPECT_TRUE(body.ok()) << body.status().to_string();
  return {std::move(*m), std::move(*body)};
}

lb::Fluid make_test_fluid(lb::Precision precision) {
  lb::FluidParams p;
  p.nx = p.ny = p.nz = kBox;
  p.tau = 1.0;
  p.walls_y = true;  // walls at rest
  p.force_field = true;
  p.velocity_field = true;
  p.precision = precision;
  StatusOr<lb::Fluid> f = lb::make_fluid(p);
  EXPECT_TRUE(f.ok()) << f.status().to_string();
  return std::move(*f);
}

class RestTest : public ::testing::TestWithParam<lb::Precision> {};

// A stress-free cell in a fluid at rest: the coupled update must not move it.
// The elastic forces at the reference configuration are round-off (~1e-16 of
// mu R^2); after 300 steps every vertex must still be within 1e-10 lattice
// spacings of where it started.
TEST_P(RestTest, ForceFreeCellInFluidAtRestStaysAtRest) {
  const Cell cell = make_cell(400);
  const units::Units u = test_units();
  lb::Fluid fluid = make_test_fluid(GetParam());
  const double centre[3] = {0.5 * kBox, 0.5 * kBox, 0.5 * kBox};
  ImmersedCells cells;
  ImmersedCell& immersed = add_cell(cells, cell.mesh, cell.body, u, centre);
  const std::vector<double> start = immersed.positions_lattice;
  lb::update_velocity_field(fluid);
  double max_force = 0.0;
  for (int step = 0; step < 300; ++step) {
    const elastic::ElasticEvaluation eval = compute_elastic_forces(immersed, 1);
    ASSERT_LT(eval.first_inverted_tet, 0);
    for (double f : immersed.forces_lattice) max_force = std::max(max_force, std::abs(f));
    spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);
    lb::collide_stream(fluid);
    const AdvectReport report = advect_cell(immersed, fluid, ibm::Kernel::kPeskin4, 1);
    ASSERT_TRUE(std::isfinite(report.max_speed_lattice));
  }
  double max_displacement = 0.0;
  for (std::size_t i = 0; i < start.size(); ++i) {
    max_displacement = std::max(max_displacement, std::abs(immersed.positions_lattice[i] - start[i]));
  }
  EXPECT_LT(max_displacement, 1e-10) << "largest elastic force at rest " << max_force << " (lattice units)";
  std::printf("at rest after 300 steps: max displacement %.2e, max force %.2e (lattice units)\n",
              max_displacement, max_force);
}

INSTANTIATE_TEST_SUITE_P(Precisions, RestTest,
                         ::testing::Values(lb::Precision::kDouble, lb::Precision::kFloat));

// Deforms the cell: an affine stretch with shear plus waves of 0.15 lattice
// spacings and about 1.2 radii wavelength, a function of the position (not
// of the vertex numbering, which the mesher may change).
void deform(ImmersedCell& cell) {
  const std::size_t nv = cell.positions_lattice.size() / 3;
  for (std::size_t v = 0; v < nv; ++v) {
    double* x = &cell.positions_lattice[3 * v];
    const double r[3] = {x[0] - cell.origin_lattice[0], x[1] - cell.origin_lattice[1],
                         x[2] - cell.origin_lattice[2]};
    x[0] = cell.origin_lattice[0] + 1.2 * r[0] + 0.1 * r[1] + 0.15 * std::sin(1.0 + 1.1 * r[1] + 0.7 * r[2]);
    x[1] = cell.origin_lattice[1] + 0.9 * r[1] + 0.15 * std::sin(2.0 + 1.3 * r[2] + 0.5 * r[0]);
    x[2] = cell.origin_lattice[2] + 0.95 * r[2] + 0.15 * std::sin(3.0 + 0.9 * r[0] + 1.2 * r[1]);
  }
}

struct Moments {
  std::array<double, 3> force{0, 0, 0};
  std::array<double, 3> torque{0, 0, 0};  // about the box centre
  double force_scale = 0.0;               // sum |F|
  double torque_scale = 0.0;              // sum |r| |F|
};

void add_moment(Moments& m, const double r[3], const double f[3]) {
  for (int d = 0; d < 3; ++d) m.force[d] += f[d];
  // tau = r x f
  m.torque[0] += r[1] * f[2] - r[2] * f[1];
  m.torque[1] += r[2] * f[0] - r[0] * f[2];
  m.torque[2] += r[0] * f[1] - r[1] * f[0];
  const double fn = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  m.force_scale += fn;
  m.torque_scale += std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) * fn;
}

Moments point_moments(const ImmersedCell& cell, const double centre[3]) {
  Moments m;
  for (std::size_t v = 0; v < cell.positions_lattice.size() / 3; ++v) {
    const double r[3] = {cell.positions_lattice[3 * v] - centre[0],
                         cell.positions_lattice[3 * v + 1] - centre[1],
                         cell.positions_lattice[3 * v + 2] - centre[2]};
    add_moment(m, r, &cell.forces_lattice[3 * v]);
  }
  return m;
}

Moments field_moments(lb::Fluid& fluid, const double centre[3]) {
  Moments m;
  const lb::VectorField<double> f = fluid.force_field<double>();
  for (int k = 0; k < fluid.nz(); ++k) {
    for (int j = 0; j < fluid.ny(); ++j) {
      for (int i = 0; i < fluid.nx(); ++i) {
        const std::size_t n = fluid.node(i, j, k);
        // node (i, j, k) sits at (i + 1/2, j + 1/2, k + 1/2)
        const double r[3] = {i + 0.5 - centre[0], j + 0.5 - centre[1], k + 0.5 - centre[2]};
        const double force[3] = {f.x[n], f.y[n], f.z[n]};
        add_moment(m, r, force);
      }
    }
  }
  return m;
}

void expect_same_moments(const Moments& lattice, const Moments& points) {
  double force_error = 0.0, torque_error = 0.0;
  for (int d = 0; d < 3; ++d) {
    force_error = std::max(force_error, std::abs(lattice.force[d] - points.force[d]) / points.force_scale);
    torque_error =
        std::max(torque_error, std::abs(lattice.torque[d] - points.torque[d]) / points.torque_scale);
  }
  std::printf("spread: total force error %.1e of sum |F|, torque error %.1e of sum |r||F|\n", force_error,
              torque_error);
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(lattice.force[d], points.force[d], 1e-12 * points.force_scale) << "force component " << d;
    EXPECT_NEAR(lattice.torque[d], points.torque[d], 1e-12 * points.torque_scale) << "torque component " << d;
  }
}

// Peskin kernels have unit zeroth and vanishing first moments, so the lattice
// receives the total force and the total torque of the vertex forces, to
// round-off. Checked for the balanced elastic forces of a deformed cell
// (total ~0) and for an unbalanced half of them (total nonzero).
TEST(ImmersedCell, SpreadingConservesTotalForceAndTorque) {
  const Cell cell = make_cell(1000);
  const units::Units u = test_units();
  for (const ibm::Kernel kernel : {ibm::Kernel::kPeskin4, ibm::Kernel::kPeskin3, ibm::Kernel::kTrilinear}) {
    SCOPED_TRACE(std::string(ibm::kernel_name(kernel)));
    lb::Fluid fluid = make_test_fluid(lb::Precision::kDouble);
    const double centre[3] = {0.5 * kBox + 0.3, 0.5 * kBox - 0.2, 0.5 * kBox + 0.1};
    ImmersedCells cells;
    ImmersedCell& immersed = add_cell(cells, cell.mesh, cell.body, u, centre);
    deform(immersed);
    const elastic::ElasticEvaluation eval = compute_elastic_forces(immersed, 1);
    ASSERT_LT(eval.first_inverted_tet, 0);
    ASSERT_GT(eval.energy_j, 0.0);

    const Moments points = point_moments(immersed, centre);
    ASSERT_GT(points.force_scale, 0.0);
    spread_forces(cells, fluid, kernel, 1);
    expect_same_moments(field_moments(fluid, centre), points);

    // Unbalanced: only the vertices with x above the centre push.
    for (std::size_t v = 0; v < immersed.positions_lattice.size() / 3; ++v) {
      if (immersed.positions_lattice[3 * v] < centre[0]) {
        for (int d = 0; d < 3; ++d) immersed.forces_lattice[3 * v + d] = 0.0;
      }
    }
    const Moments half = point_moments(immersed, centre);
    EXPECT_GT(std::abs(half.force[0]) + std::abs(half.force[1]) + std::abs(half.force[2]),
              0.1 * half.force_scale / 1000);
    spread_forces(cells, fluid, kernel, 1);  // clears the previous spread first
    expect_same_moments(field_moments(fluid, centre), half);
  }
}

// spread_forces clears only the nodes the previous spread touched: after
// the cell has moved, the field must equal a spread onto a cleared lattice.
TEST(ImmersedCell, LocalClearingLeavesNoStaleForce) {
  const Cell cell = make_cell(400);
  const units::Units u = test_units();
  lb::Fluid fluid = make_test_fluid(lb::Precision::kDouble);
  lb::Fluid reference = make_test_fluid(lb::Precision::kDouble);
  // Near the periodic x boundary so that the cleared box wraps around.
  const double centre[3] = {2.5, 0.5 * kBox, 0.5 * kBox};
  ImmersedCells cells;
  ImmersedCell& immersed = add_cell(cells, cell.mesh, cell.body, u, centre);
  deform(immersed);
  ASSERT_LT(compute_elastic_forces(immersed, 1).first_inverted_tet, 0);
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);
  // Move by 1.7 spacings in x and 0.6 in y, recompute, spread again.
  for (std::size_t v = 0; v < immersed.positions_lattice.size() / 3; ++v) {
    immersed.positions_lattice[3 * v] += 1.7;
    immersed.positions_lattice[3 * v + 1] += 0.6;
  }
  immersed.origin_lattice[0] += 1.7;
  immersed.origin_lattice[1] += 0.6;
  ASSERT_LT(compute_elastic_forces(immersed, 1).first_inverted_tet, 0);
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);

  ImmersedCells fresh = cells;
  fresh[0].last_support = NodeBox{};
  lb::zero_force_field(reference);
  spread_forces(fresh, reference, ibm::Kernel::kPeskin4, 1);
  const lb::VectorField<double> a = fluid.force_field<double>();
  const lb::VectorField<double> b = reference.force_field<double>();
  double max_difference = 0.0, max_force = 0.0;
  for (std::size_t n = 0; n < fluid.num_nodes(); ++n) {
    max_difference = std::max(
        {max_difference, std::abs(a.x[n] - b.x[n]), std::abs(a.y[n] - b.y[n]), std::abs(a.z[n] - b.z[n])});
    max_force = std::max({max_force, std::abs(b.x[n]), std::abs(b.y[n]), std::abs(b.z[n])});
  }
  ASSERT_GT(max_force, 0.0);
  EXPECT_EQ(max_difference, 0.0);
}

// Two cells whose spreading supports overlap (centres 7.3 spacings apart,
// radius 4 spacings): the cells interact only through the fluid.
constexpr double kCentreA[3] = {8.3, 12.2, 12.1};
constexpr double kCentreB[3] = {15.6, 11.7, 12.4};

ImmersedCells two_deformed_cells(const Cell& a, const Cell& b, const units::Units& u) {
  ImmersedCells cells;
  add_cell(cells, a.mesh, a.body, u, kCentreA);
  add_cell(cells, b.mesh, b.body, u, kCentreB);
  for (ImmersedCell& c : cells.cells) deform(c);
  return cells;
}

ImmersedCells only(const ImmersedCells& cells, std::size_t i) {
  ImmersedCells one;
  one.cells.push_back(cells[i]);
  return one;
}

double max_abs_field(lb::Fluid& fluid) {
  const lb::VectorField<double> f = fluid.force_field<double>();
  double m = 0.0;
  for (std::size_t n = 0; n < fluid.num_nodes(); ++n) {
    m = std::max({m, std::abs(f.x[n]), std::abs(f.y[n]), std::abs(f.z[n])});
  }
  return m;
}

// The elastic forces of each cell are those of the cell alone, and spreading
// is linear: the field of both cells is the sum of the fields each cell alone
// spreads (to round-off where the supports overlap).
TEST(ImmersedCells, SpreadingTwoCellsIsTheSumOfEachCellsSpread) {
  const Cell a = make_cell(400);
  const Cell b = make_cell(1000);
  const units::Units u = test_units();
  ImmersedCells cells = two_deformed_cells(a, b, u);
  ImmersedCells alone[2] = {only(cells, 0), only(cells, 1)};
  const std::vector<elastic::ElasticEvaluation> evals = compute_elastic_forces(cells, 1);
  ASSERT_EQ(evals.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const elastic::ElasticEvaluation single = compute_elastic_forces(alone[i][0], 1);
    ASSERT_LT(evals[i].first_inverted_tet, 0);
    EXPECT_GT(evals[i].energy_j, 0.0);
    EXPECT_EQ(evals[i].energy_j, single.energy_j) << "cell " << i;
    EXPECT_EQ(cells[i].forces_lattice, alone[i][0].forces_lattice) << "cell " << i;
  }

  lb::Fluid both = make_test_fluid(lb::Precision::kDouble);
  lb::Fluid field_a = make_test_fluid(lb::Precision::kDouble);
  lb::Fluid field_b = make_test_fluid(lb::Precision::kDouble);
  spread_forces(cells, both, ibm::Kernel::kPeskin4, 1);
  spread_forces(alone[0], field_a, ibm::Kernel::kPeskin4, 1);
  spread_forces(alone[1], field_b, ibm::Kernel::kPeskin4, 1);
  // Each cell records its own support, not the union.
  for (std::size_t i = 0; i < 2; ++i) {
    for (int d = 0; d < 3; ++d) {
      EXPECT_EQ(cells[i].last_support.lo[d], alone[i][0].last_support.lo[d]);
      EXPECT_EQ(cells[i].last_support.hi[d], alone[i][0].last_support.hi[d]);
    }
  }
  const lb::VectorField<double> f = both.force_field<double>();
  const lb::VectorField<double> fa = field_a.force_field<double>();
  const lb::VectorField<double> fb = field_b.force_field<double>();
  const double scale = max_abs_field(both);
  ASSERT_GT(scale, 0.0);
  double max_difference = 0.0;
  int overlap = 0;
  for (std::size_t n = 0; n < both.num_nodes(); ++n) {
    max_difference =
        std::max({max_difference, std::abs(f.x[n] - (fa.x[n] + fb.x[n])),
                  std::abs(f.y[n] - (fa.y[n] + fb.y[n])), std::abs(f.z[n] - (fa.z[n] + fb.z[n]))});
    if (fa.x[n] != 0.0 && fb.x[n] != 0.0) ++overlap;
  }
  EXPECT_GT(overlap, 0) << "the supports of the two cells do not overlap";
  EXPECT_LE(max_difference, 1e-12 * scale);
  std::printf("two cells: %d nodes in both supports, |F - (F_a + F_b)| <= %.1e of max |F|\n", overlap,
              max_difference / scale);
}

// After both cells have moved, the local clearing must remove the previous
// spreads of both (the union of their supports) before either spreads again:
// the field equals both spread onto a cleared lattice, exactly.
TEST(ImmersedCells, ClearingCoversThePreviousSupportsOfBothCells) {
  const Cell a = make_cell(400);
  const Cell b = make_cell(400);
  const units::Units u = test_units();
  lb::Fluid fluid = make_test_fluid(lb::Precision::kDouble);
  lb::Fluid reference = make_test_fluid(lb::Precision::kDouble);
  ImmersedCells cells = two_deformed_cells(a, b, u);
  ASSERT_LT(compute_elastic_forces(cells, 1)[0].first_inverted_tet, 0);
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);
  // Towards each other (A's new support overlaps B's old one) and apart in z.
  const double shift[2][3] = {{1.7, 0.6, -0.8}, {-1.3, -0.4, 0.9}};
  for (std::size_t i = 0; i < 2; ++i) {
    for (std::size_t v = 0; v < cells[i].positions_lattice.size() / 3; ++v) {
      for (int d = 0; d < 3; ++d) cells[i].positions_lattice[3 * v + d] += shift[i][d];
    }
    for (int d = 0; d < 3; ++d) cells[i].origin_lattice[d] += shift[i][d];
  }
  for (const elastic::ElasticEvaluation& eval : compute_elastic_forces(cells, 1)) {
    ASSERT_LT(eval.first_inverted_tet, 0);
  }
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);

  ImmersedCells fresh = cells;
  for (ImmersedCell& c : fresh.cells) c.last_support = NodeBox{};
  lb::zero_force_field(reference);
  spread_forces(fresh, reference, ibm::Kernel::kPeskin4, 1);
  const lb::VectorField<double> x = fluid.force_field<double>();
  const lb::VectorField<double> y = reference.force_field<double>();
  double max_difference = 0.0;
  for (std::size_t n = 0; n < fluid.num_nodes(); ++n) {
    max_difference = std::max(
        {max_difference, std::abs(x.x[n] - y.x[n]), std::abs(x.y[n] - y.y[n]), std::abs(x.z[n] - y.z[n])});
  }
  ASSERT_GT(max_abs_field(reference), 0.0);
  EXPECT_EQ(max_difference, 0.0);
}

// In a linear shear u_x = s (y - y0) each vertex moves by the velocity
// interpolated at its own position (linear fields interpolate exactly), so
// the two cells, below and above y0, move in opposite directions; each moves
// exactly as it would alone.
TEST(ImmersedCells, AdvectMovesEachCellByItsOwnInterpolatedVelocity) {
  const Cell a = make_cell(400);
  const Cell b = make_cell(400);
  const units::Units u = test_units();
  lb::Fluid fluid = make_test_fluid(lb::Precision::kDouble);
  constexpr double kShear = 1e-3, kY0 = 0.5 * kBox;
  {
    // u_x = s (y - y0) at the nodes y = j + 1/2
    std::vector<double> ux(fluid.num_nodes(), 0.0), zero(fluid.num_nodes(), 0.0);
    for (int k = 0; k < kBox; ++k) {
      for (int j = 0; j < kBox; ++j) {
        for (int i = 0; i < kBox; ++i) ux[fluid.node(i, j, k)] = kShear * (j + 0.5 - kY0);
      }
    }
    lb::set_equilibrium(fluid, {}, ux, zero, zero);
    lb::update_velocity_field(fluid);
  }
  const double below[3] = {0.5 * kBox, 7.0, 0.5 * kBox}, above[3] = {0.5 * kBox + 0.4, 17.0, 0.5 * kBox};
  ImmersedCells cells;
  add_cell(cells, a.mesh, a.body, u, below);
  add_cell(cells, b.mesh, b.body, u, above);
  ImmersedCells alone[2] = {only(cells, 0), only(cells, 1)};
  const ImmersedCells start = cells;

  const std::vector<AdvectReport> reports = advect_cells(cells, fluid, ibm::Kernel::kPeskin4, 1);
  ASSERT_EQ(reports.size(), 2u);
  double mean_dx[2] = {0.0, 0.0};
  for (std::size_t i = 0; i < 2; ++i) {
    const AdvectReport single = advect_cell(alone[i][0], fluid, ibm::Kernel::kPeskin4, 1);
    EXPECT_EQ(cells[i].positions_lattice, alone[i][0].positions_lattice) << "cell " << i;
    EXPECT_EQ(reports[i].max_speed_lattice, single.max_speed_lattice) << "cell " << i;
    const std::vector<double>& x0 = start[i].positions_lattice;
    const std::vector<double>& x1 = cells[i].positions_lattice;
    const std::size_t nv = x0.size() / 3;
    for (std::size_t v = 0; v < nv; ++v) {
      // X += U dt with U = (s (Y - y0), 0, 0)
      EXPECT_NEAR(x1[3 * v] - x0[3 * v], kShear * (x0[3 * v + 1] - kY0), 1e-12)
          << "cell " << i << " vertex " << v;
      EXPECT_NEAR(x1[3 * v + 1], x0[3 * v + 1], 1e-12);
      EXPECT_NEAR(x1[3 * v + 2], x0[3 * v + 2], 1e-12);
      mean_dx[i] += (x1[3 * v] - x0[3 * v]) / static_cast<double>(nv);
    }
  }
  // The vertex mean lies within a tenth of a spacing of the placed centre.
  EXPECT_NEAR(mean_dx[0], kShear * (below[1] - kY0), 0.1 * kShear);
  EXPECT_NEAR(mean_dx[1], kShear * (above[1] - kY0), 0.1 * kShear);
  EXPECT_LT(mean_dx[0], 0.0);
  EXPECT_GT(mean_dx[1], 0.0);
}

// advect_cells interpolates with the stencils of the last spread_forces when
// the points have not moved since (the flow step), and with new ones when
// they have: in a sheared flow that also varies along z, the vertices end
// bit for bit where advect_cell (fresh stencils, one cell alone) puts them,
// with the points unchanged, with the points moved after the spread, and
// with scaled markers.
TEST(ImmersedCells, AdvectReusesTheSpreadsStencilsOnlyForUnmovedPoints) {
  const Cell a = make_cell(400);
  const Cell b = make_cell(400);
  const units::Units u = test_units();
  lb::Fluid fluid = make_test_fluid(lb::Precision::kFloat);
  {
    std::vector<double> ux(fluid.num_nodes(), 0.0), uy(fluid.num_nodes(), 0.0), zero(fluid.num_nodes(), 0.0);
    for (int k = 0; k < kBox; ++k) {
      for (int j = 0; j < kBox; ++j) {
        for (int i = 0; i < kBox; ++i) {
          ux[fluid.node(i, j, k)] = 1e-3 * (j + 0.5 - 0.5 * kBox) + 1e-4 * std::sin(0.5 * k);
          uy[fluid.node(i, j, k)] = 2e-4 * std::cos(0.3 * i + 0.2 * k);
        }
      }
    }
    lb::set_equilibrium(fluid, {}, ux, uy, zero);
    lb::update_velocity_field(fluid);
  }
  const double below[3] = {0.5 * kBox, 8.0, 0.5 * kBox}, above[3] = {0.5 * kBox + 0.4, 16.0, 0.5 * kBox};
  for (const double scale : {1.0, 0.9}) {
    for (const bool move_after_spread : {false, true}) {
      ImmersedCells cells;
      add_cell(cells, a.mesh, a.body, u, below);
      add_cell(cells, b.mesh, b.body, u, above);
      for (ImmersedCell& cell : cells.cells) cell.marker_scale = scale;
      // A deformed state, so that there are forces to spread.
      for (double& x : cells[1].positions_lattice) x *= 1.0 + 1e-3;
      compute_elastic_forces(cells, 1);
      spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 2);
      if (move_after_spread) {
        for (std::size_t v = 0; v < cells[0].positions_lattice.size() / 3; ++v) {
          cells[0].positions_lattice[3 * v + 1] += 0.3;
        }
      }
      ImmersedCells alone[2] = {only(cells, 0), only(cells, 1)};
      const std::vector<AdvectReport>& reports = advect_cells(cells, fluid, ibm::Kernel::kPeskin4, 2);
      ASSERT_EQ(reports.size(), 2u);
      for (std::size_t i = 0; i < 2; ++i) {
        const AdvectReport single = advect_cell(alone[i][0], fluid, ibm::Kernel::kPeskin4, 1);
        EXPECT_EQ(cells[i].positions_lattice, alone[i][0].positions_lattice)
            << "cell " << i << " scale " << scale << " moved " << move_after_spread;
        EXPECT_EQ(reports[i].max_speed_lattice, single.max_speed_lattice);
      }
    }
  }
}

// Scaled markers (ImmersedCell::marker_scale, the shear-flow scene's
// hydrodynamic radius correction): the lattice receives the first moment
// sum F (X - c) of the vertex forces (the stresslet and the torque) to
// round-off, although the forces F / s sit at c + s (X - c); and in a linear
// flow the vertices move with the flow's velocity at their own positions
// (U_c + (U_m - U_c) / s undoes the scaling exactly).
TEST(ImmersedCell, ScaledMarkersKeepTheFirstMomentAndFollowALinearFlow) {
  const Cell cell = make_cell(1000);
  const units::Units u = test_units();
  constexpr double kScale = 0.9;
  lb::Fluid fluid = make_test_fluid(lb::Precision::kDouble);
  const double centre[3] = {0.5 * kBox + 0.3, 0.5 * kBox - 0.2, 0.5 * kBox + 0.1};
  ImmersedCells cells;
  ImmersedCell& immersed = add_cell(cells, cell.mesh, cell.body, u, centre);
  immersed.marker_scale = kScale;
  deform(immersed);
  ASSERT_LT(compute_elastic_forces(immersed, 1).first_inverted_tet, 0);
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);

  const std::size_t nv = immersed.positions_lattice.size() / 3;
  double c[3] = {0, 0, 0};
  for (std::size_t v = 0; v < nv; ++v) {
    for (int d = 0; d < 3; ++d) c[d] += immersed.positions_lattice[3 * v + d] / static_cast<double>(nv);
  }
  // M_ab = sum F_a (X_b - c_b) over the vertices and sum f_a (x_b - c_b) over the nodes.
  double points[3][3] = {}, lattice[3][3] = {}, scale = 0.0;
  for (std::size_t v = 0; v < nv; ++v) {
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        const double m = immersed.forces_lattice[3 * v + a] * (immersed.positions_lattice[3 * v + b] - c[b]);
        points[a][b] += m;
        scale += std::abs(m);
      }
    }
  }
  const lb::VectorField<double> f = fluid.force_field<double>();
  for (int k = 0; k < fluid.nz(); ++k) {
    for (int j = 0; j < fluid.ny(); ++j) {
      for (int i = 0; i < fluid.nx(); ++i) {
        const std::size_t n = fluid.node(i, j, k);
        const double r[3] = {i + 0.5 - c[0], j + 0.5 - c[1], k + 0.5 - c[2]};
        const double force[3] = {f.x[n], f.y[n], f.z[n]};
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) lattice[a][b] += force[a] * r[b];
        }
      }
    }
  }
  ASSERT_GT(scale, 0.0);
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      EXPECT_NEAR(lattice[a][b], points[a][b], 1e-12 * scale) << "first moment " << a << b;
    }
  }
  std::printf("scaled markers: first moment xy %.6e (vertices) %.6e (lattice)\n", points[0][1],
              lattice[0][1]);

  // u = (g (y - y0), h (x - x0), 0) on every node: linear, so interpolated exactly.
  const double g = 1e-3, h = -4e-4, y0 = 11.0, x0 = 13.0;
  std::vector<double> ux(fluid.num_nodes()), uy(fluid.num_nodes()), uz(fluid.num_nodes(), 0.0);
  for (int k = 0; k < fluid.nz(); ++k) {
    for (int j = 0; j < fluid.ny(); ++j) {
      for (int i = 0; i < fluid.nx(); ++i) {
        ux[fluid.node(i, j, k)] = g * (j + 0.5 - y0);
        uy[fluid.node(i, j, k)] = h * (i + 0.5 - x0);
      }
    }
  }
  lb::zero_force_field(fluid);
  lb::set_equilibrium(fluid, {}, ux, uy, uz);
  lb::update_velocity_field(fluid);
  const std::vector<double> before = immersed.positions_lattice;
  advect_cell(immersed, fluid, ibm::Kernel::kPeskin4, 1);
  for (std::size_t v = 0; v < nv; ++v) {
    const double expected[3] = {g * (before[3 * v + 1] - y0), h * (before[3 * v] - x0), 0.0};
    for (int d = 0; d < 3; ++d) {
      ASSERT_NEAR(immersed.velocities_lattice[3 * v + d], expected[d], 1e-12)
          << "vertex " << v << " dir " << d;
    }
  }
}

// Viscosity contrast (ImmersedCells::phase_spread_weights): with a phase
// field a point's kernel weights on phase-1 nodes are scaled by g and the
// stencil renormalised, so the point's force is kept and its inside share
// falls by g against the outside share; without weights the plain spread.
TEST(ImmersedCell, PhaseSpreadWeightMovesForceOutOfTheInsideAndKeepsIt) {
  const Cell cell = make_cell(300);
  const units::Units u = test_units();
  lb::FluidParams fp;
  fp.nx = fp.ny = fp.nz = kBox;
  fp.tau = 1.0;
  fp.force_field = true;
  fp.velocity_field = true;
  fp.precision = lb::Precision::kDouble;
  fp.phase_taus = {0.525};
  StatusOr<lb::Fluid> made = lb::make_fluid(fp);
  ASSERT_TRUE(made.ok()) << made.status().to_string();
  lb::Fluid fluid = std::move(*made);
  const double centre[3] = {0.5 * kBox, 0.5 * kBox, 0.5 * kBox};
  // Inside: nodes (at i + 1/2) within 4 dx of the centre.
  std::vector<std::uint8_t> phases(fluid.num_nodes(), 0);
  for (int k = 0; k < kBox; ++k)
    for (int j = 0; j < kBox; ++j)
      for (int i = 0; i < kBox; ++i) {
        const double r = std::hypot(i + 0.5 - centre[0], j + 0.5 - centre[1], k + 0.5 - centre[2]);
        phases[fluid.node(i, j, k)] = r < 4.0 ? 1 : 0;
      }
  ASSERT_TRUE(lb::set_phases(fluid, phases).ok());

  ImmersedCells cells;
  ImmersedCell& immersed = add_cell(cells, cell.mesh, cell.body, u, centre);
  // One surface vertex (on the 4 dx sphere, i.e. on the jump) pushes.
  std::size_t pusher = 0;
  while (!cell.mesh.on_surface[pusher]) ++pusher;
  std::fill(immersed.forces_lattice.begin(), immersed.forces_lattice.end(), 0.0);
  const double force[3] = {1e-3, -2e-3, 0.5e-3};
  for (int d = 0; d < 3; ++d) immersed.forces_lattice[3 * pusher + d] = force[d];

  // Total force and the inside's part of it, per component.
  auto shares = [&](std::array<double, 3>& total, std::array<double, 3>& inside) {
    const lb::VectorField<const double> f = std::as_const(fluid).force_field<double>();
    total = {0, 0, 0};
    inside = {0, 0, 0};
    for (std::size_t n = 0; n < fluid.num_nodes(); ++n) {
      const double v[3] = {f.x[n], f.y[n], f.z[n]};
      for (int d = 0; d < 3; ++d) {
        total[d] += v[d];
        if (phases[n]) inside[d] += v[d];
      }
    }
  };
  std::array<double, 3> total1, inside1, total_g, inside_g, total_one, inside_one;
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);
  shares(total1, inside1);
  // Weight 1 in both phases: the weighted path gives the plain spread.
  cells.phase_spread_weights = {1.0, 1.0};
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);
  shares(total_one, inside_one);
  const double g = 0.25;
  cells.phase_spread_weights = {1.0, g};
  spread_forces(cells, fluid, ibm::Kernel::kPeskin4, 1);
  shares(total_g, inside_g);
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(total1[d], force[d], 1e-15);
    EXPECT_NEAR(total_g[d], force[d], 1e-15);
    EXPECT_NEAR(inside_one[d], inside1[d], 1e-15);
    // Both sides of the jump take part, and the ratio inside / outside falls by g.
    ASSERT_GT(std::abs(inside1[d]), 0.05 * std::abs(force[d]));
    ASSERT_GT(std::abs(force[d] - inside1[d]), 0.05 * std::abs(force[d]));
    const double ratio1 = inside1[d] / (total1[d] - inside1[d]);
    const double ratio_g = inside_g[d] / (total_g[d] - inside_g[d]);
    EXPECT_NEAR(ratio_g / ratio1, g, 1e-12);
  }
}

}  // namespace
}  // namespace cellflow::coupling
