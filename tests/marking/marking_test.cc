// Inside/outside marking of lattice nodes (physics/marking): the marked
// volume of a cell at rest equals its mesh volume; the fast band update
// agrees with the exact winding-number test on every node at sampled steps
// of a cell that moves, rotates, deforms and crosses a periodic boundary;
// a jump beyond the band falls back to the exact test; bad params are refused
// by name; the phases land in the fluid.
#include "physics/marking/marking.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "physics/lb/fluid.h"
#include "physics/mesh/sphere_mesh.h"

namespace cellflow::marking {
namespace {

constexpr double kRadiusM = 1e-6;

mesh::TetMesh sphere(int vertices) {
  mesh::SphereMeshOptions options;
  options.radius_m = kRadiusM;
  options.target_vertex_count = vertices;
  StatusOr<mesh::TetMesh> m = mesh::make_sphere_mesh(options);
  EXPECT_TRUE(m.ok()) << m.status().to_string();
  return std::move(*m);
}

// The mesh scaled to `radius` lattice units about `centre`.
coupling::ImmersedCell place(const mesh::TetMesh& mesh, double radius, const double centre[3]) {
  coupling::ImmersedCell cell;
  cell.mesh = &mesh;
  cell.positions_lattice.resize(mesh.positions_m.size());
  for (std::size_t i = 0; i < mesh.positions_m.size(); ++i)
    cell.positions_lattice[i] = centre[i % 3] + mesh.positions_m[i] * radius / kRadiusM;
  return cell;
}

lb::Fluid fluid_of(int nx, int ny, int nz) {
  lb::FluidParams p;
  p.nx = nx;
  p.ny = ny;
  p.nz = nz;
  p.phase_taus = {0.55};
  StatusOr<lb::Fluid> f = lb::make_fluid(p);
  EXPECT_TRUE(f.ok()) << f.status().to_string();
  return std::move(*f);
}

double mesh_volume_lattice(const coupling::ImmersedCell& cell) {
  double v = 0.0;
  const std::vector<std::int32_t>& t = cell.mesh->tets;
  const double* x = cell.positions_lattice.data();
  for (std::size_t e = 0; e + 3 < t.size(); e += 4) {
    const double* a = x + 3 * t[e];
    const double* b = x + 3 * t[e + 1];
    const double* c = x + 3 * t[e + 2];
    const double* d = x + 3 * t[e + 3];
    const double u[3] = {a[0] - d[0], a[1] - d[1], a[2] - d[2]};
    const double w[3] = {b[0] - d[0], b[1] - d[1], b[2] - d[2]};
    const double s[3] = {c[0] - d[0], c[1] - d[1], c[2] - d[2]};
    v += (u[0] * (w[1] * s[2] - w[2] * s[1]) - u[1] * (w[0] * s[2] - w[2] * s[0]) +
          u[2] * (w[0] * s[1] - w[1] * s[0])) /
         6.0;
  }
  return std::abs(v);
}

TEST(Marking, MarkedVolumeOfACellAtRestEqualsTheMeshVolume) {
  const mesh::TetMesh mesh = sphere(1000);
  // Off the lattice's symmetry, at two radii.
  for (double radius : {6.0, 8.0}) {
    const double centre[3] = {16.27, 15.61, 16.93};
    coupling::ImmersedCells cells;
    cells.cells.push_back(place(mesh, radius, centre));
    const lb::Fluid fluid = fluid_of(32, 32, 32);
    StatusOr<NodeMarking> m = make_marking(cells, fluid, {});
    ASSERT_TRUE(m.ok()) << m.status().to_string();
    const double marked = static_cast<double>(m->count_inside(0));
    const double volume = mesh_volume_lattice(cells[0]);
    std::printf("radius %.0f: %.0f marked nodes, mesh volume %.1f, ratio %.4f\n", radius, marked, volume,
                marked / volume);
    EXPECT_NEAR(marked / volume, 1.0, 0.02)
        << "radius " << radius << ": " << marked << " nodes, mesh " << volume;
    EXPECT_EQ(m->stats().full_markings, 1);
  }
}

// x(t): translation along x across the periodic boundary, a rotation about
// z and a volume-preserving stretch growing with t.
void deform(const coupling::ImmersedCell& rest, const double centre[3], double t,
            coupling::ImmersedCell& cell) {
  const double angle = 0.9 * t, stretch = 1.0 + 0.5 * t;
  const double c = std::cos(angle), s = std::sin(angle);
  for (std::size_t v = 0; v < rest.positions_lattice.size() / 3; ++v) {
    const double x = rest.positions_lattice[3 * v] - centre[0];
    const double y = rest.positions_lattice[3 * v + 1] - centre[1];
    const double z = rest.positions_lattice[3 * v + 2] - centre[2];
    const double sx = stretch * x, sy = y / std::sqrt(stretch), sz = z / std::sqrt(stretch);
    cell.positions_lattice[3 * v] = centre[0] + 14.0 * t + c * sx - s * sy;
    cell.positions_lattice[3 * v + 1] = centre[1] + s * sx + c * sy;
    cell.positions_lattice[3 * v + 2] = centre[2] + sz + 0.3 * std::sin(2.0 * sx);
  }
}

TEST(Marking, FastUpdateAgreesWithTheExactTestOnEveryNodeOfAMovingDeformingCell) {
  const mesh::TetMesh mesh = sphere(1000);
  const double centre[3] = {20.3, 12.4, 12.7};
  const coupling::ImmersedCell rest = place(mesh, 5.0, centre);
  coupling::ImmersedCells cells;
  cells.cells.push_back(rest);
  const lb::Fluid fluid = fluid_of(32, 25, 26);
  MarkingParams params;
  params.band_lattice = 1.0;
  StatusOr<NodeMarking> fast = make_marking(cells, fluid, params);
  ASSERT_TRUE(fast.ok()) << fast.status().to_string();
  const int steps = 200;
  int compared = 0;
  for (int step = 1; step <= steps; ++step) {
    deform(rest, centre, static_cast<double>(step) / steps, cells[0]);  // 0.07 lattice units a step at most
    update_marking(*fast, cells);
    if (step % 25 != 0) continue;
    StatusOr<NodeMarking> exact = make_marking(cells, fluid, params);
    ASSERT_TRUE(exact.ok());
    std::size_t differ = 0;
    for (std::size_t n = 0; n < fluid.num_nodes(); ++n) differ += fast->owner()[n] != exact->owner()[n];
    EXPECT_EQ(differ, 0u) << "step " << step;
    EXPECT_GT(exact->count_inside(0), 300u);
    ++compared;
  }
  EXPECT_EQ(compared, 8);
  // Only band updates: no cell moved beyond the band between two updates.
  EXPECT_EQ(fast->stats().full_markings, 1);
  EXPECT_EQ(fast->stats().updates, steps);
  EXPECT_GT(fast->stats().band_nodes, 0);
  // The cell crossed x = 32: its nodes wrap to the box's other side.
  const std::span<const std::int32_t> owner = fast->owner();
  bool low_x = false;
  for (int k = 0; k < 26; ++k)
    for (int j = 0; j < 25; ++j) low_x = low_x || owner[fluid.node(0, j, k)] == 0;
  EXPECT_TRUE(low_x);
}

TEST(Marking, AJumpBeyondTheBandFallsBackToTheExactTest) {
  const mesh::TetMesh mesh = sphere(500);
  const double centre[3] = {12.5, 12.5, 12.5};
  coupling::ImmersedCells cells;
  cells.cells.push_back(place(mesh, 4.0, centre));
  const lb::Fluid fluid = fluid_of(28, 28, 28);
  StatusOr<NodeMarking> m = make_marking(cells, fluid, {});
  ASSERT_TRUE(m.ok());
  const std::size_t before = m->count_inside(0);
  for (std::size_t i = 0; i < cells[0].positions_lattice.size(); i += 3) cells[0].positions_lattice[i] += 3.0;
  update_marking(*m, cells);
  EXPECT_EQ(m->stats().full_markings, 2);
  StatusOr<NodeMarking> exact = make_marking(cells, fluid, {});
  ASSERT_TRUE(exact.ok());
  for (std::size_t n = 0; n < fluid.num_nodes(); ++n) ASSERT_EQ(m->owner()[n], exact->owner()[n]) << n;
  EXPECT_EQ(m->count_inside(0), before);  // a shift by whole spacings
}

TEST(Marking, PhasesLandInTheFluidAndBadInputIsRefused) {
  const mesh::TetMesh mesh = sphere(500);
  const double centre[3] = {10.2, 10.6, 10.1};
  coupling::ImmersedCells cells;
  cells.cells.push_back(place(mesh, 4.0, centre));
  lb::Fluid fluid = fluid_of(20, 20, 20);
  StatusOr<NodeMarking> m = make_marking(cells, fluid, {});
  ASSERT_TRUE(m.ok());
  const std::uint8_t phase_of_cell[1] = {1};
  ASSERT_TRUE(apply_phases(*m, phase_of_cell, fluid).ok());
  std::size_t ones = 0;
  for (std::uint8_t p : fluid.phases()) ones += p == 1;
  EXPECT_EQ(ones, m->count_inside(0));
  const std::uint8_t too_high[1] = {2};  // the fluid has one phase_tau
  EXPECT_FALSE(apply_phases(*m, too_high, fluid).ok());

  MarkingParams bad;
  bad.band_lattice = 0.1;
  StatusOr<NodeMarking> refused = make_marking(cells, fluid, bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("band_lattice"), std::string::npos);
  // A cell wider than a periodic box.
  coupling::ImmersedCells wide;
  wide.cells.push_back(place(mesh, 9.5, centre));
  StatusOr<NodeMarking> too_wide = make_marking(wide, fluid, {});
  ASSERT_FALSE(too_wide.ok());
  EXPECT_NE(too_wide.status().message().find("wider than the box"), std::string::npos);
}

}  // namespace
}  // namespace cellflow::marking
