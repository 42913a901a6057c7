// Inside/outside marking of lattice nodes (physics/marking): the marked
// volume of a cell at rest equals its mesh volume; the fast band update
// agrees with the exact winding-number test on every node at sampled steps
// of a cell that moves, rotates, deforms and crosses a periodic boundary;
// a jump beyond the band falls back to the exact test; bad params are refused
// by name; the phases land in the fluid.
#include "physics/marking/marking.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
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

// The reference: the winding number (inside_exact) evaluated at every node
// of every cell's bounding box (nodes outside it lie outside the convex hull),
// later cells over earlier ones, as make_marking orders them.
std::vector<std::int32_t> brute_force_owner(const coupling::ImmersedCells& cells, const lb::Fluid& fluid) {
  const int n[3] = {fluid.nx(), fluid.ny(), fluid.nz()};
  std::vector<std::int32_t> owner(fluid.num_nodes(), -1);
  for (std::size_t c = 0; c < cells.size(); ++c) {
    const std::vector<std::int32_t> tris = surface_triangles(cells[c]);
    const std::vector<double>& x = cells[c].positions_lattice;
    int first[3], last[3];
    for (int d = 0; d < 3; ++d) {
      double lo = x[d], hi = x[d];
      for (std::size_t i = d; i < x.size(); i += 3) lo = std::min(lo, x[i]), hi = std::max(hi, x[i]);
      first[d] = static_cast<int>(std::ceil(lo - 0.5));
      last[d] = static_cast<int>(std::floor(hi - 0.5));
    }
    if (fluid.params().walls_y) first[1] = std::max(first[1], 0), last[1] = std::min(last[1], n[1] - 1);
    for (int k = first[2]; k <= last[2]; ++k)
      for (int j = first[1]; j <= last[1]; ++j)
        for (int i = first[0]; i <= last[0]; ++i) {
          const double p[3] = {i + 0.5, j + 0.5, k + 0.5};
          if (!inside_exact(cells[c], tris, p)) continue;
          const int w[3] = {(i % n[0] + n[0]) % n[0], (j % n[1] + n[1]) % n[1], (k % n[2] + n[2]) % n[2]};
          owner[fluid.node(w[0], w[1], w[2])] = static_cast<std::int32_t>(c);
        }
  }
  return owner;
}

std::size_t count_differing(std::span<const std::int32_t> a, const std::vector<std::int32_t>& b) {
  std::size_t differ = 0;
  for (std::size_t n = 0; n < b.size(); ++n) differ += a[n] != b[n];
  return differ;
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
    // The full marking evaluates the winding number only once per region of
    // nodes far from the surface, and agrees with it at every node.
    EXPECT_EQ(count_differing(m->owner(), brute_force_owner(cells, fluid)), 0u) << "radius " << radius;
    EXPECT_LT(m->stats().exact_node_tests, static_cast<std::int64_t>(marked) / 4);
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
    const std::vector<std::int32_t> exact = brute_force_owner(cells, fluid);
    EXPECT_EQ(count_differing(fast->owner(), exact), 0u) << "step " << step;
    EXPECT_GT(std::count(exact.begin(), exact.end(), 0), 300);
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
  EXPECT_EQ(count_differing(m->owner(), brute_force_owner(cells, fluid)), 0u);
  EXPECT_EQ(m->count_inside(0), before);  // a shift by whole spacings
}

// A suspension: six cells in two layers sheared past each other (gaps of
// about one lattice spacing), each rotating and stretching, crossing the
// periodic boundary in x, between walls in y. Marked every step and every 5
// steps; both agree with the winding number on every node at sampled steps.
TEST(Marking, FastUpdateAgreesWithTheExactTestForSeveralCellsNearEachOther) {
  const mesh::TetMesh mesh = sphere(500);
  const double radius = 4.0;
  const lb::Fluid fluid = fluid_of(27, 21, 14);
  // Layer centres y = 5.6 and 15.3: 1.7 spacings between the layers' surfaces
  // at rest; 9 spacings between centres in x (1 between surfaces).
  std::vector<std::array<double, 3>> centres;
  for (int layer = 0; layer < 2; ++layer)
    for (int c = 0; c < 3; ++c) centres.push_back({1.3 + 9.0 * c + 2.0 * layer, 5.6 + 9.7 * layer, 7.1});
  coupling::ImmersedCells rest;
  for (const auto& c : centres) rest.cells.push_back(place(mesh, radius, c.data()));
  coupling::ImmersedCells cells = rest;
  MarkingParams every_step, every_five;
  every_five.band_lattice = 1.5;
  StatusOr<NodeMarking> fast1 = make_marking(cells, fluid, every_step);
  StatusOr<NodeMarking> fast5 = make_marking(cells, fluid, every_five);
  ASSERT_TRUE(fast1.ok()) << fast1.status().to_string();
  ASSERT_TRUE(fast5.ok()) << fast5.status().to_string();
  EXPECT_EQ(count_differing(fast1->owner(), brute_force_owner(cells, fluid)), 0u) << "start";
  const int steps = 150;
  for (int step = 1; step <= steps; ++step) {
    const double t = static_cast<double>(step) / steps;
    for (std::size_t c = 0; c < cells.size(); ++c) {
      // Layers move apart in x by 0.05 spacings a step; each cell rotates
      // about z and stretches along x by up to 5 % (volume kept).
      const double shift = (c < 3 ? -1.0 : 1.0) * 3.75 * t;
      const double angle = (c % 2 == 0 ? 0.6 : -0.4) * t, stretch = 1.0 + 0.05 * std::sin(3.0 * t);
      const double cs = std::cos(angle), sn = std::sin(angle);
      const std::vector<double>& x0 = rest[c].positions_lattice;
      std::vector<double>& x = cells[c].positions_lattice;
      for (std::size_t v = 0; v < x0.size(); v += 3) {
        const double rx = stretch * (x0[v] - centres[c][0]),
                     ry = (x0[v + 1] - centres[c][1]) / std::sqrt(stretch);
        const double rz = (x0[v + 2] - centres[c][2]) / std::sqrt(stretch);
        x[v] = centres[c][0] + shift + cs * rx - sn * ry;
        x[v + 1] = centres[c][1] + sn * rx + cs * ry;
        x[v + 2] = centres[c][2] + rz;
      }
    }
    update_marking(*fast1, cells);
    if (step % 5 == 0) update_marking(*fast5, cells);
    if (step % 30 != 0) continue;
    const std::vector<std::int32_t> exact = brute_force_owner(cells, fluid);
    EXPECT_EQ(count_differing(fast1->owner(), exact), 0u) << "every step, step " << step;
    EXPECT_EQ(count_differing(fast5->owner(), exact), 0u) << "every 5 steps, step " << step;
    for (int c = 0; c < 6; ++c) EXPECT_GT(std::count(exact.begin(), exact.end(), c), 150) << c;
  }
  // No fallback: only the exact markings of the start.
  EXPECT_EQ(fast1->stats().full_markings, 6);
  EXPECT_EQ(fast5->stats().full_markings, 6);
  // Each update re-marks only the nodes the surfaces could have crossed: far
  // fewer than the cells' volume.
  EXPECT_LT(fast1->stats().band_nodes, 6 * 150 * 150);
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
