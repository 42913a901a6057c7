// Each scene computes only what it needs (issue 5, item 4):
// - a compression or indentation job allocates no lattice: the contact-scene
//   library cellflow::scenes does not link the lattice-Boltzmann, immersed-
//   boundary or unit modules at all (link closure written at configure time);
// - a single-cell flow builds no cell-cell contact search: cellflow::shear_flow
//   links no contact module and no quasi-static solver;
// - w = 1 takes the neo-Hookean path, and that path does not evaluate the
//   Mooney-Rivlin K term;
// - a flow run stops at steady state, not at its maximum strain or time,
//   once D has converged.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "physics/cell/cell_body.h"
#include "physics/cell/cell_params.h"
#include "physics/elastic/elastic_body.h"
#include "physics/elastic/material.h"
#include "physics/scenes/quasi_static/quasi_static.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "scene_link_closure.h"

namespace cellflow::scene_needs {
namespace {

template <std::size_t N>
bool links(const char* const (&closure)[N], std::string_view target) {
  return std::find(std::begin(closure), std::end(closure), target) != std::end(closure);
}

template <std::size_t N>
std::string listed(const char* const (&closure)[N]) {
  std::string out;
  for (const char* t : closure) out += std::string(t) + " ";
  return out;
}

TEST(SceneLinkClosure, CompressionAndIndentationLinkNoLattice) {
  const std::string all = listed(kContactScenesClosure);
  // The walk reached the modules the contact scenes do use.
  for (const char* used : {"cellflow_quasi_static", "cellflow_core", "cellflow_mesh", "cellflow_elastic",
                           "cellflow_contact", "cellflow_solver", "cellflow_observables"}) {
    EXPECT_TRUE(links(kContactScenesClosure, used)) << used << " missing from: " << all;
  }
  // No fluid: no lattice can be allocated by code that is not linked.
  for (const char* unused : {"cellflow_lb", "cellflow_ibm", "cellflow_units", "cellflow_shear_flow"}) {
    EXPECT_FALSE(links(kContactScenesClosure, unused)) << unused << " linked by cellflow::scenes: " << all;
  }
}

TEST(SceneLinkClosure, ShearFlowBuildsNoContactSearchAndNoSolver) {
  const std::string all = listed(kShearFlowClosure);
  for (const char* used : {"cellflow_shear_flow", "cellflow_lb", "cellflow_ibm", "cellflow_units",
                           "cellflow_elastic", "cellflow_mesh", "cellflow_observables"}) {
    EXPECT_TRUE(links(kShearFlowClosure, used)) << used << " missing from: " << all;
  }
  for (const char* t : kShearFlowClosure) {
    // physics/contact is the only contact code; a cell-cell search would be a
    // contact target too.
    EXPECT_EQ(std::string_view(t).find("contact"), std::string_view::npos)
        << "cellflow::shear_flow links " << t << ": " << all;
  }
  EXPECT_FALSE(links(kShearFlowClosure, "cellflow_solver")) << all;
  EXPECT_FALSE(links(kShearFlowClosure, "cellflow_quasi_static")) << all;
}

TEST(SceneLinkClosure, OnlyTheSuspensionBuildsTheCellContactSearch) {
  // The suspension scene links the cell-cell repulsion; the single-cell
  // scene it builds on does not (checked above for every contact target).
  const std::string all = listed(kSuspensionClosure);
  EXPECT_TRUE(links(kSuspensionClosure, "cellflow_cell_contact")) << all;
  EXPECT_TRUE(links(kSuspensionClosure, "cellflow_shear_flow")) << all;
  EXPECT_FALSE(links(kShearFlowClosure, "cellflow_cell_contact")) << listed(kShearFlowClosure);
  EXPECT_FALSE(links(kShearFlowClosure, "cellflow_suspension")) << listed(kShearFlowClosure);
  EXPECT_FALSE(links(kContactScenesClosure, "cellflow_suspension")) << listed(kContactScenesClosure);
}

// The body as the compression scene builds it (quasi_static.cc:
// cell::build_cell_body, the cell mesh with the cytoplasm and nucleus materials).
elastic::ElasticBody scene_body(const cell::CellParams& cell) {
  StatusOr<cell::CellBody> built = cell::build_cell_body(cell, elastic::VolumetricTerm::kPerTet);
  EXPECT_TRUE(built.ok()) << built.status().to_string();
  return std::move(built->body);
}

cell::CellParams cell_with_w(double w) {
  cell::CellParams cell;
  cell.radius_m = 8.6e-6;
  cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.48, .mooney_rivlin_w = w};
  cell.target_vertex_count = 200;
  return cell;
}

TEST(NeoHookeanPath, WOneGivesANeoHookeanBody) {
  const elastic::ElasticBody nh = scene_body(cell_with_w(1.0));
  EXPECT_TRUE(nh.neo_hookean);
  EXPECT_TRUE(std::all_of(nh.mu2_pa.begin(), nh.mu2_pa.end(), [](double mu2) { return mu2 == 0.0; }));

  EXPECT_FALSE(scene_body(cell_with_w(0.5)).neo_hookean);
  // A Mooney-Rivlin nucleus in a neo-Hookean cytoplasm needs the K term.
  cell::CellParams mixed = cell_with_w(1.0);
  mixed.nucleus = cell::NucleusParams{
      .radius_m = 4e-6,
      .material = {.youngs_modulus_pa = 1e4, .poisson_ratio = 0.48, .mooney_rivlin_w = 0.5}};
  EXPECT_FALSE(scene_body(mixed).neo_hookean);
}

// Timing-free evidence that the neo-Hookean path skips the K term: give a
// neo-Hookean body a non-zero mu2 behind its back. Forces, energy and tangent
// do not change while the flag is set (mu2 is never read), and do change once
// the flag is cleared (the Mooney-Rivlin path reads it).
TEST(NeoHookeanPath, TheNeoHookeanKernelNeverEvaluatesTheKTerm) {
  const elastic::ElasticBody nh = scene_body(cell_with_w(1.0));
  ASSERT_TRUE(nh.neo_hookean);
  const std::size_t n = 3 * nh.num_vertices;
  // A smooth finite deformation of the mesh: stretch, shear and a twist.
  StatusOr<mesh::TetMesh> m = cell::build_cell_mesh(cell_with_w(1.0));
  ASSERT_TRUE(m.ok());
  std::vector<double> y = m->positions_m;
  for (std::size_t v = 0; v < nh.num_vertices; ++v) {
    const double x0 = y[3 * v], x1 = y[3 * v + 1], x2 = y[3 * v + 2];
    y[3 * v] = 1.2 * x0 + 0.1 * x1;
    y[3 * v + 1] = 0.9 * x1 + 0.05 * std::sin(x2 / 8.6e-6) * 8.6e-6;
    y[3 * v + 2] = 0.95 * x2;
  }

  elastic::ElasticBody with_mu2 = nh;
  for (std::size_t t = 0; t < with_mu2.num_tets(); ++t) with_mu2.mu2_pa[t] = 0.5 * with_mu2.mu1_pa[t];
  elastic::ElasticBody mooney_rivlin = with_mu2;
  mooney_rivlin.neo_hookean = false;

  auto forces = [&](const elastic::ElasticBody& body, double& energy) {
    std::vector<double> f(n, 0.0);
    const elastic::ElasticEvaluation e = elastic::add_elastic_forces(body, y.data(), f.data(), 1);
    EXPECT_LT(e.first_inverted_tet, 0);
    energy = e.energy_j;
    return f;
  };
  double e_nh = 0.0, e_hidden = 0.0, e_mr = 0.0;
  const std::vector<double> f_nh = forces(nh, e_nh);
  const std::vector<double> f_hidden = forces(with_mu2, e_hidden);
  const std::vector<double> f_mr = forces(mooney_rivlin, e_mr);
  EXPECT_EQ(e_nh, e_hidden);
  EXPECT_EQ(f_nh, f_hidden);
  ASSERT_GT(e_nh, 0.0);
  // The K term adds mu2/2 (K - 3) >= 0 per tet: a visible difference.
  EXPECT_GT(e_mr, e_nh * (1.0 + 1e-3));
  double difference = 0.0, scale = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    difference = std::max(difference, std::abs(f_mr[i] - f_nh[i]));
    scale = std::max(scale, std::abs(f_nh[i]));
  }
  EXPECT_GT(difference, 1e-3 * scale);

  auto tangent = [&](const elastic::ElasticBody& body) {
    elastic::TangentAssembler assembler(body);
    assembler.set_threads(1);
    assembler.assemble(y.data());
    const Eigen::SparseMatrix<double>& k = assembler.stiffness();
    return std::vector<double>(k.valuePtr(), k.valuePtr() + k.nonZeros());
  };
  const std::vector<double> k_nh = tangent(nh);
  EXPECT_EQ(k_nh, tangent(with_mu2));
  EXPECT_NE(k_nh, tangent(mooney_rivlin));
}

// A small fast flow (4 cells per radius, box 6 x 6 x 4 R, 400 vertices,
// Ca 0.1) whose D settles within ~10 strain units: the run ends there, with
// the limits (500 strain units, 10^6 s) far away.
scenes::ShearFlowParams small_flow() {
  scenes::ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material = {.youngs_modulus_pa = 1.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  // 600 vertices: on 400 the tank-treading mesh makes D fluctuate by +-1.7 %,
  // more than the 5e-3 band of the steady criterion (steady only after 62
  // strain units); 600 are steady after 6.5
  p.cell.target_vertex_count = 600;
  p.capillary_number = 0.1;
  scenes::ShearFlowNumerics& n = p.numerics;
  n.cells_per_radius = 4.0;
  n.box_x_radii = 6.0;
  n.box_y_radii = 6.0;
  n.box_z_radii = 4.0;
  n.steady_tolerance = 5e-3;
  n.steady_window_strain = 2.0;
  n.max_strain = 500.0;
  n.max_time_s = 1e6;
  n.snapshot_every_strain = 0.0;
  n.threads = 1;
  return p;
}

TEST(ShearFlowStop, StopsAtSteadyStateLongBeforeTheLimits) {
  const scenes::ShearFlowParams p = small_flow();
  const scenes::ShearFlowResult r = scenes::run_shear_flow(p);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  EXPECT_EQ(r.stop, scenes::ShearFlowStop::kSteady) << scenes::stop_name(r.stop);
  ASSERT_FALSE(r.samples.empty());
  const scenes::ShearFlowSample& last = r.samples.back();
  std::printf("steady after strain %.2f (%lld steps, %.2f s wall), D %.4f, relative change %.2e\n",
              last.strain_units, static_cast<long long>(r.time_steps), r.wall_time_s,
              r.steady_taylor_deformation, r.steady_relative_change);
  EXPECT_LT(last.strain_units, 0.1 * p.numerics.max_strain);
  EXPECT_LT(last.time_s, 1e-3 * p.numerics.max_time_s);
  // It stopped because D had converged: over the last window D changed by
  // less than the tolerance, and it had moved well away from the sphere.
  EXPECT_LT(r.steady_relative_change, p.numerics.steady_tolerance);
  EXPECT_GT(r.steady_taylor_deformation, 0.5 * scenes::small_ca_taylor_deformation(p.capillary_number));
}

TEST(ShearFlowStop, WithoutTheSteadyCriterionTheRunGoesToTheLimit) {
  scenes::ShearFlowParams p = small_flow();
  p.numerics.steady_tolerance = 0.0;  // steady stop disabled
  p.numerics.max_strain = 2.0;
  const scenes::ShearFlowResult r = scenes::run_shear_flow(p);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  EXPECT_EQ(r.stop, scenes::ShearFlowStop::kMaxStrain) << scenes::stop_name(r.stop);
  EXPECT_NEAR(r.samples.back().strain_units, 2.0, 0.01);
}

}  // namespace
}  // namespace cellflow::scene_needs
