// Tangent stiffness K = d^2E/dy^2 from TangentAssembler: finite differences of
// the forces, symmetry, sparsity pattern, re-assembly and threads.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <random>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "tests/elastic/elastic_test_util.h"

namespace cellflow::elastic::testing {
namespace {

// K by central differences of the forces: K_(:,k) = -(f(y + h e_k) - f(y - h e_k)) / 2h.
Eigen::MatrixXd finite_difference_tangent(const ElasticBody& body, std::vector<double> y, double h) {
  const auto n = static_cast<Eigen::Index>(y.size());
  Eigen::MatrixXd k(n, n);
  for (Eigen::Index c = 0; c < n; ++c) {
    const double saved = y[c];
    y[c] = saved + h;
    const std::vector<double> plus = forces_at(body, y);
    y[c] = saved - h;
    const std::vector<double> minus = forces_at(body, y);
    y[c] = saved;
    for (Eigen::Index r = 0; r < n; ++r) k(r, c) = -(plus[r] - minus[r]) / (2.0 * h);
  }
  return k;
}

// K with both parts (stiffness() and, for the nodal-averaged volumetric
// term, the applied G^T C G), column by column through multiply().
Eigen::MatrixXd dense_tangent(const TangentAssembler& assembler) {
  const Eigen::Index n = assembler.stiffness().cols();
  Eigen::MatrixXd k(n, n);
  Eigen::VectorXd unit = Eigen::VectorXd::Zero(n), column(n);
  for (Eigen::Index c = 0; c < n; ++c) {
    unit[c] = 1.0;
    assembler.multiply(unit.data(), column.data());
    k.col(c) = column;
    unit[c] = 0.0;
  }
  return k;
}

class ElasticTangentIsForceDerivative : public ::testing::TestWithParam<MaterialCase> {};

// Relative error max |K - K_fd| / max |K| below 1e-6 (step 1e-5 of an edge).
TEST_P(ElasticTangentIsForceDerivative, BoxAndRandomTets) {
  const MaterialCase c = GetParam();
  std::mt19937 rng(4321);
  const mesh::TetMesh box = make_box_mesh(2, 2, 2, kBoxSize, kBoxSize, kBoxSize);
  const mesh::TetMesh tets = random_tets(4, rng);
  for (const mesh::TetMesh* mesh : {&box, &tets}) {
    const ElasticBody body = make_body(*mesh, material(c.w, c.nu), c.volumetric);
    TangentAssembler assembler(body);
    for (int sample = 0; sample < 2; ++sample) {
      const std::vector<double> y = random_deformation(*mesh, rng, 0.03 * first_edge_m(*mesh));
      std::vector<double> f(y.size(), 0.0);
      const ElasticEvaluation eval = assembler.assemble(y.data(), f.data());
      ASSERT_EQ(eval.first_inverted_tet, -1);
      EXPECT_EQ(assembler.has_volumetric_operator(), c.volumetric == VolumetricTerm::kNodalAverage);
      const Eigen::MatrixXd k = dense_tangent(assembler);
      // the diagonal blocks the preconditioners see are those of K
      std::vector<double> blocks(9 * body.num_vertices, 0.0);
      const Eigen::MatrixXd sparse_part(assembler.stiffness());
      assembler.add_volumetric_diagonal_blocks(blocks.data());
      for (std::size_t v = 0; v < body.num_vertices; ++v) {
        for (int i = 0; i < 3; ++i) {
          for (int j = 0; j < 3; ++j) {
            const Eigen::Index r = static_cast<Eigen::Index>(3 * v + i),
                               col = static_cast<Eigen::Index>(3 * v + j);
            EXPECT_NEAR(sparse_part(r, col) + blocks[9 * v + 3 * i + j], k(r, col),
                        1e-12 * k.cwiseAbs().maxCoeff());
          }
        }
      }
      const Eigen::MatrixXd k_fd = finite_difference_tangent(body, y, 1e-5 * first_edge_m(*mesh));
      const double k_max = k.cwiseAbs().maxCoeff();
      EXPECT_LT((k - k_fd).cwiseAbs().maxCoeff() / k_max, 1e-6);
      // Symmetric to rounding.
      EXPECT_LT((k - k.transpose()).cwiseAbs().maxCoeff() / k_max, 1e-13);
      // The same pass gives the energy and forces of add_elastic_forces.
      const double energy = elastic_energy(body, y.data()).energy_j;
      EXPECT_NEAR(eval.energy_j, energy, 1e-13 * energy);
      EXPECT_LT(relative_error(f, forces_at(body, y)), 1e-13);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, ElasticTangentIsForceDerivative, ::testing::ValuesIn(kMaterialCases),
                         case_name);

// Small-strain limit: at the reference state K is the linear-elastic stiffness,
// positive semi-definite with exactly six zero modes (rigid motions).
TEST(ElasticTangent, ReferenceStateHasSixRigidModes) {
  const mesh::TetMesh mesh = make_box_mesh(2, 2, 2, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(mesh, material(0.5, 0.3));
  TangentAssembler assembler(body);
  assembler.assemble(mesh.positions_m.data());
  const Eigen::MatrixXd k(assembler.stiffness());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(k);
  const Eigen::VectorXd& values = eigen.eigenvalues();
  const double largest = values.maxCoeff();
  for (int m = 0; m < 6; ++m) EXPECT_LT(std::abs(values[m]), 1e-12 * largest);
  EXPECT_GT(values[6], 1e-4 * largest);
}

// The pattern is the vertex adjacency: a 3x3 block for every pair of vertices
// sharing a tet; re-assembly overwrites (does not accumulate) the values.
TEST(ElasticTangent, PatternAndReassembly) {
  std::mt19937 rng(8);
  const mesh::TetMesh mesh = make_box_mesh(3, 2, 2, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(mesh, material(0.25, 0.45));
  TangentAssembler assembler(body);
  const auto n = static_cast<Eigen::Index>(3 * mesh.num_vertices());
  ASSERT_EQ(assembler.stiffness().rows(), n);
  ASSERT_EQ(assembler.stiffness().cols(), n);
  Eigen::MatrixXi adjacent = Eigen::MatrixXi::Zero(n / 3, n / 3);
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) adjacent(mesh.tets[4 * t + a], mesh.tets[4 * t + b]) = 1;
    }
  }
  EXPECT_EQ(assembler.stiffness().nonZeros(), 9 * adjacent.sum());
  const std::vector<double> y = random_deformation(mesh, rng, 0.02 * kBoxSize);
  assembler.assemble(y.data());
  const Eigen::MatrixXd first(assembler.stiffness());
  assembler.assemble(y.data());
  const Eigen::MatrixXd second(assembler.stiffness());
  EXPECT_EQ((first - second).cwiseAbs().maxCoeff(), 0.0);
  for (Eigen::Index r = 0; r < n; ++r) {
    for (Eigen::Index c = 0; c < n; ++c) {
      if (!adjacent(r / 3, c / 3)) {
        EXPECT_EQ(first(r, c), 0.0);
      }
    }
  }
}

// Colour-parallel assembly equals the serial one.
TEST(ElasticTangent, TwoThreadsMatchOne) {
  std::mt19937 rng(21);
  const mesh::TetMesh mesh = make_box_mesh(8, 8, 8, kBoxSize, kBoxSize, kBoxSize);  // 3072 tets
  const ElasticBody body = make_body(mesh, material(0.5, 0.45));
  const std::vector<double> y = random_deformation(mesh, rng, 0.02 * kBoxSize / 8);
  TangentAssembler serial(body), parallel(body);
  serial.set_threads(1);
  parallel.set_threads(2);
  std::vector<double> f1(y.size(), 0.0);
  std::vector<double> f2(y.size(), 0.0);
  const double e1 = serial.assemble(y.data(), f1.data()).energy_j;
  const double e2 = parallel.assemble(y.data(), f2.data()).energy_j;
  EXPECT_NEAR(e2, e1, 1e-13 * e1);
  EXPECT_LT(relative_error(f2, f1), 1e-13);
  // Same pattern, so the value arrays compare entry by entry.
  const Eigen::SparseMatrix<double>& k1 = serial.stiffness();
  const Eigen::SparseMatrix<double>& k2 = parallel.stiffness();
  ASSERT_EQ(k1.nonZeros(), k2.nonZeros());
  double diff = 0.0, largest = 0.0;
  for (Eigen::Index k = 0; k < k1.nonZeros(); ++k) {
    diff = std::max(diff, std::abs(k1.valuePtr()[k] - k2.valuePtr()[k]));
    largest = std::max(largest, std::abs(k1.valuePtr()[k]));
  }
  EXPECT_LT(diff, 1e-13 * largest);
  // Dynamic scheduling of the colour groups does not change a bit of the result.
  std::vector<double> f3(y.size(), 0.0);
  const std::vector<double> values2(k2.valuePtr(), k2.valuePtr() + k2.nonZeros());
  EXPECT_EQ(parallel.assemble(y.data(), f3.data()).energy_j, e2);
  EXPECT_EQ(f3, f2);
  EXPECT_EQ(std::vector<double>(k2.valuePtr(), k2.valuePtr() + k2.nonZeros()), values2);
}

}  // namespace
}  // namespace cellflow::elastic::testing
