// The SIMD copies of the force loop (elastic_forces.cc, one per level the CPU
// supports) against a scalar reference: the stages of tet_kernel.h run one tet
// at a time, as the tangent does, on a randomly deformed box and on random
// tetrahedra, with full and partial lane blocks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/elastic/tet_kernel.h"
#include "tests/elastic/elastic_test_util.h"

namespace cellflow::elastic::testing {
namespace {

struct RangeResult {
  std::vector<double> forces;
  double energy_j = 0.0;
  std::int64_t first_inverted = -1;
};

// Forces and isochoric + per-tet energy of tets [begin, end), tet after tet.
// The nodal-averaged volumetric term enters as the library's per-tet mean
// pressures (the same inputs; only the tet loop is under test here).
RangeResult scalar_reference(const ElasticBody& body, const std::vector<double>& y, std::int64_t begin,
                             std::int64_t end, const std::vector<double>& tet_pressure) {
  RangeResult r;
  r.forces.assign(y.size(), 0.0);
  for (std::int64_t t = begin; t < end; ++t) {
    const std::int32_t* v = body.tets.data() + 4 * t;
    kernel::TetParams p{body.b_matrix.data() + 9 * t, body.ref_volume_m3[t], body.mu1_pa[t],
                        body.neo_hookean ? 0.0 : body.mu2_pa[t], body.kappa_pa[t]};
    if (!tet_pressure.empty()) {
      p.kappa_pa = 0.0;
      p.pressure_pa = tet_pressure[t];
    }
    kernel::TetStress s;
    const double* yv[4];
    for (int a = 0; a < 4; ++a) yv[a] = y.data() + 3 * static_cast<std::int64_t>(v[a]);
    const bool ok = body.neo_hookean ? kernel::tet_stress<false>(p, yv[0], yv[1], yv[2], yv[3], s)
                                     : kernel::tet_stress<true>(p, yv[0], yv[1], yv[2], yv[3], s);
    if (!ok) {
      if (r.first_inverted < 0) r.first_inverted = t;
      continue;
    }
    double f[12];
    kernel::forces_from_stress(p.b_matrix, p.ref_volume_m3, s.stress, f);
    r.energy_j += p.ref_volume_m3 * s.energy_density[0];
    for (int a = 0; a < 4; ++a) {
      for (int i = 0; i < 3; ++i) r.forces[3 * static_cast<std::int64_t>(v[a]) + i] += f[3 * a + i];
    }
  }
  return r;
}

// kNodalAverage: the per-tet mean of the vertex pressures
// p_a = (kappa V)_a / V_a (Jbar_a - 1), recomputed here from the body's vertex
// data (the equations are in elastic_forces.cc, volumetric_pressures).
std::vector<double> mean_nodal_pressures(const ElasticBody& body, const std::vector<double>& y) {
  std::vector<double> pressures;
  if (body.volumetric != VolumetricTerm::kNodalAverage) return pressures;
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  std::vector<double> tet_volume(num_tets);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = body.tets.data() + 4 * t;
    const double* y3 = y.data() + 3 * v[3];
    double d[9];
    for (int k = 0; k < 3; ++k) {
      for (int i = 0; i < 3; ++i) d[3 * i + k] = y[3 * v[k] + i] - y3[i];
    }
    tet_volume[t] = (d[0] * (d[4] * d[8] - d[5] * d[7]) + d[1] * (d[5] * d[6] - d[3] * d[8]) +
                     d[2] * (d[3] * d[7] - d[4] * d[6])) /
                    6.0;
  }
  std::vector<double> vertex_pressure(body.num_vertices, 0.0);
  for (std::size_t a = 0; a < body.num_vertices; ++a) {
    const double volume = body.vertex_volume_m3[a];
    if (volume <= 0.0) continue;
    double deformed = 0.0;
    for (std::int64_t k = body.vertex_tet_offsets[a]; k < body.vertex_tet_offsets[a + 1]; ++k)
      deformed += tet_volume[body.vertex_tets[k]];
    vertex_pressure[a] = body.vertex_bulk_volume_j[a] / volume * (0.25 * deformed / volume - 1.0);
  }
  pressures.resize(num_tets);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = body.tets.data() + 4 * t;
    pressures[t] = 0.25 * (vertex_pressure[v[0]] + vertex_pressure[v[1]] + vertex_pressure[v[2]] +
                           vertex_pressure[v[3]]);
  }
  return pressures;
}

double volumetric_energy(const ElasticBody& body, const std::vector<double>& y) {
  if (body.volumetric != VolumetricTerm::kNodalAverage) return 0.0;
  // The range call adds the whole volumetric energy; an empty range isolates it.
  std::vector<double> scratch(y.size(), 0.0);
  return add_elastic_forces_of_range(body, y.data(), scratch.data(), 0, 0, TetSimd::kGeneric).energy_j;
}

constexpr TetSimd kLevels[] = {TetSimd::kGeneric, TetSimd::kAvx2, TetSimd::kAvx512};

class ElasticSimdForces : public ::testing::TestWithParam<MaterialCase> {};

// Every supported level: forces and energy equal to the scalar reference to
// 1e-12 relative, and bit for bit equal to the generic level (no FMA
// contraction, same operation order). Ranges cover whole blocks of 16 lanes,
// a partial last block and fewer tets than one block.
TEST_P(ElasticSimdForces, EqualScalarReferenceAtEveryLevel) {
  const MaterialCase c = GetParam();
  std::mt19937 rng(99);
  const mesh::TetMesh box = make_box_mesh(5, 4, 3, kBoxSize, kBoxSize, 0.8 * kBoxSize);
  const mesh::TetMesh tets = random_tets(37, rng);
  int levels_run = 0;
  for (const mesh::TetMesh* mesh : {&box, &tets}) {
    const ElasticBody body = make_body(*mesh, material(c.w, c.nu), c.volumetric);
    const std::vector<double> y = random_deformation(*mesh, rng, 0.1 * first_edge_m(*mesh));
    const std::vector<double> pressures = mean_nodal_pressures(body, y);
    const double e_volumetric = volumetric_energy(body, y);
    const std::int64_t n = static_cast<std::int64_t>(body.num_tets());
    const std::int64_t ranges[][2] = {{0, n}, {3, n - 2}, {5, 14}};
    for (const auto& range : ranges) {
      const RangeResult reference = scalar_reference(body, y, range[0], range[1], pressures);
      ASSERT_EQ(reference.first_inverted, -1);
      std::vector<double> generic(y.size(), 0.0);
      const ElasticEvaluation eval_generic =
          add_elastic_forces_of_range(body, y.data(), generic.data(), range[0], range[1], TetSimd::kGeneric);
      for (const TetSimd level : kLevels) {
        if (!tet_simd_supported(level)) continue;
        ++levels_run;
        SCOPED_TRACE(tet_simd_name(level));
        std::vector<double> forces(y.size(), 0.0);
        const ElasticEvaluation eval =
            add_elastic_forces_of_range(body, y.data(), forces.data(), range[0], range[1], level);
        EXPECT_EQ(eval.first_inverted_tet, -1);
        EXPECT_GT(max_abs(forces), 0.0);
        EXPECT_LT(relative_error(forces, reference.forces), 1e-12);
        EXPECT_NEAR(eval.energy_j - e_volumetric, reference.energy_j, 1e-12 * std::abs(reference.energy_j));
        EXPECT_EQ(forces, generic);
        EXPECT_EQ(eval.energy_j, eval_generic.energy_j);
      }
    }
  }
  EXPECT_GE(levels_run, 6);  // the generic level at least, on both meshes and all ranges
}

INSTANTIATE_TEST_SUITE_P(Cases, ElasticSimdForces, ::testing::ValuesIn(kMaterialCases), case_name);

// An inverted tet inside a lane block is reported (the first one of the range)
// and adds nothing, at every level, while its block neighbours still count.
TEST(ElasticSimdForces, InvertedTetInsideBlockAtEveryLevel) {
  const mesh::TetMesh box = make_box_mesh(4, 4, 2, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(box, material(0.5, 0.3));
  std::vector<double> y = box.positions_m;
  // Push vertex 0 of tet 20 through the opposite face: it inverts tet 20 (and
  // maybe other tets at that vertex; the first of them is reported).
  const std::int32_t* v = body.tets.data() + 4 * 20;
  double centroid[3] = {0.0, 0.0, 0.0};
  for (int a = 1; a < 4; ++a) {
    for (int i = 0; i < 3; ++i) centroid[i] += box.positions_m[3 * v[a] + i] / 3.0;
  }
  for (int i = 0; i < 3; ++i) y[3 * v[0] + i] = 3.0 * centroid[i] - 2.0 * box.positions_m[3 * v[0] + i];
  const std::int64_t n = static_cast<std::int64_t>(body.num_tets());
  const RangeResult reference = scalar_reference(body, y, 0, n, {});
  ASSERT_GE(reference.first_inverted, 0);
  ASSERT_LE(reference.first_inverted, 20);
  for (const TetSimd level : kLevels) {
    if (!tet_simd_supported(level)) continue;
    SCOPED_TRACE(tet_simd_name(level));
    std::vector<double> forces(y.size(), 0.0);
    const ElasticEvaluation eval = add_elastic_forces_of_range(body, y.data(), forces.data(), 0, n, level);
    EXPECT_EQ(eval.first_inverted_tet, reference.first_inverted);
    EXPECT_LT(relative_error(forces, reference.forces), 1e-12);
    EXPECT_NEAR(eval.energy_j, reference.energy_j, 1e-12 * std::abs(reference.energy_j));
  }
}

// The lane-blocked copies hold B and the vertices of every tet at its block
// and lane (zero padding after the last tet), and a body assembled without
// them (the force loop then blocks a temporary copy) gives the same bits.
TEST(ElasticSimdForces, LaneBlocksHoldEveryTetAndAreOptional) {
  const mesh::TetMesh box = make_box_mesh(3, 3, 2, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(box, material(0.5, 0.3));
  const std::size_t n = body.num_tets();
  ASSERT_NE(n % kTetBlockLanes, 0u);  // a padded last block
  const std::size_t blocks = (n + kTetBlockLanes - 1) / kTetBlockLanes;
  ASSERT_EQ(body.block_b_matrix.size(), 9 * kTetBlockLanes * blocks);
  ASSERT_EQ(body.block_vertices.size(), 4 * kTetBlockLanes * blocks);
  for (std::size_t t = 0; t < blocks * kTetBlockLanes; ++t) {
    const std::size_t block = t / kTetBlockLanes, lane = t % kTetBlockLanes;
    for (int k = 0; k < 9; ++k) {
      EXPECT_EQ(body.block_b_matrix[kTetBlockLanes * (9 * block + k) + lane],
                t < n ? body.b_matrix[9 * t + k] : 0.0);
    }
    for (int a = 0; a < 4; ++a) {
      EXPECT_EQ(body.block_vertices[kTetBlockLanes * (4 * block + a) + lane],
                t < n ? body.tets[4 * t + a] : 0);
    }
  }
  std::mt19937 rng(7);
  const std::vector<double> y = random_deformation(box, rng, 0.1 * first_edge_m(box));
  ElasticBody by_hand = body;
  by_hand.block_b_matrix.clear();
  by_hand.block_vertices.clear();
  for (const TetSimd level : kLevels) {
    if (!tet_simd_supported(level)) continue;
    SCOPED_TRACE(tet_simd_name(level));
    std::vector<double> expected(y.size(), 0.0), forces(y.size(), 0.0);
    const ElasticEvaluation a = add_elastic_forces_of_range(body, y.data(), expected.data(), 2, n, level);
    const ElasticEvaluation b = add_elastic_forces_of_range(by_hand, y.data(), forces.data(), 2, n, level);
    EXPECT_GT(max_abs(forces), 0.0);
    EXPECT_EQ(forces, expected);
    EXPECT_EQ(a.energy_j, b.energy_j);
  }
  build_lane_blocks(by_hand);
  EXPECT_EQ(by_hand.block_b_matrix, body.block_b_matrix);
  EXPECT_EQ(by_hand.block_vertices, body.block_vertices);
}

// A long range scatters into the padded accumulator (4 doubles per vertex,
// vector adds, starting from the caller's forces); short ranges scatter
// straight into the caller's array. Both add the tets to each vertex in tet
// order, so the forces come out with the same bits, from non-zero forces too,
// at every level and through add_elastic_forces.
TEST(ElasticSimdForces, PaddedAndDirectScatterGiveTheSameBits) {
  const mesh::TetMesh box = make_box_mesh(5, 4, 3, kBoxSize, kBoxSize, 0.8 * kBoxSize);
  const ElasticBody body = make_body(box, material(0.5, 0.45));
  const std::int64_t n = static_cast<std::int64_t>(body.num_tets());
  ASSERT_GE(2 * n, static_cast<std::int64_t>(body.num_vertices));               // one range: padded
  ASSERT_LT(2 * kTetBlockLanes, static_cast<std::int64_t>(body.num_vertices));  // a block: direct
  std::mt19937 rng(5);
  const std::vector<double> y = random_deformation(box, rng, 0.1 * first_edge_m(box));
  std::uniform_real_distribution<double> unit(-1e-9, 1e-9);
  std::vector<double> initial(y.size());
  for (double& f : initial) f = unit(rng);
  int levels_run = 0;
  for (const TetSimd level : kLevels) {
    if (!tet_simd_supported(level)) continue;
    ++levels_run;
    SCOPED_TRACE(tet_simd_name(level));
    std::vector<double> padded = initial, direct = initial;
    const ElasticEvaluation whole = add_elastic_forces_of_range(body, y.data(), padded.data(), 0, n, level);
    double energy = 0.0;
    for (std::int64_t begin = 0; begin < n; begin += kTetBlockLanes) {
      energy += add_elastic_forces_of_range(body, y.data(), direct.data(), begin,
                                            std::min<std::int64_t>(n, begin + kTetBlockLanes), level)
                    .energy_j;
    }
    EXPECT_NE(padded, initial);
    EXPECT_EQ(padded, direct);
    EXPECT_NEAR(whole.energy_j, energy, 1e-13 * std::abs(energy));
  }
  EXPECT_GE(levels_run, 1);
  std::vector<double> library = initial, range = initial;
  add_elastic_forces(body, y.data(), library.data(), 1);
  add_elastic_forces_of_range(body, y.data(), range.data(), 0, n);
  EXPECT_EQ(library, range);
}

TEST(ElasticSimdForces, BestLevelIsSupportedAndNamed) {
  EXPECT_TRUE(tet_simd_supported(best_tet_simd()));
  EXPECT_TRUE(tet_simd_supported(TetSimd::kGeneric));
  EXPECT_STREQ(tet_simd_name(TetSimd::kAvx512), "avx512");
}

}  // namespace
}  // namespace cellflow::elastic::testing
