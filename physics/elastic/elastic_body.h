// Vertex forces of a tetrahedral Mooney-Rivlin body:
//   f_i^a = -V0 dU/du_i^a   (paper eq. 9-10, derivative table of section 3.2)
// with F = 1 + A B, A_ik = u_i^k - u_i^4, B = J^-1 of the reference tetrahedron
// (paper eq. 11-12). B and V0 are computed once per tetrahedron.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/SparseCore>

#include "physics/core/status.h"
#include "physics/elastic/material.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::elastic {

// Precomputed reference data, one entry per tetrahedron (structure of arrays).
struct ElasticBody {
  std::vector<std::int32_t> tets;  // 4 per tet, copied from the mesh
  std::vector<double> b_matrix;    // 9 per tet, row-major B = J^-1
  std::vector<double> ref_volume_m3;  // V0 per tet
  std::vector<double> mu1_pa, mu2_pa, kappa_pa;  // per tet, from its region's material
  bool neo_hookean = true;  // every mu2 == 0: the K-term work is skipped
  std::size_t num_vertices = 0;

  std::size_t num_tets() const { return ref_volume_m3.size(); }
};

// Fails (kFailedPrecondition) on a tetrahedron with non-positive reference
// volume, naming its index. `materials` is indexed by mesh::Region.
StatusOr<ElasticBody> make_elastic_body(const mesh::TetMesh& mesh, std::span<const Material> materials);

struct ElasticEvaluation {
  double energy_j = 0.0;
  std::int64_t first_inverted_tet = -1;  // >= 0 if some J <= 0 (forces then invalid)
};

// Adds the elastic forces at deformed positions y (3 per vertex, metres) into
// forces_n and returns the elastic energy sum V0 U. Energy and forces come from
// one code path. `threads` <= 0 uses the OpenMP default.
ElasticEvaluation add_elastic_forces(const ElasticBody& body, const double* positions_m, double* forces_n,
                                     int threads = 0);

// Energy only, same arithmetic as add_elastic_forces.
ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m);

// Tangent stiffness K = d^2 E / dy dy (3 nv x 3 nv, symmetric) at y. The
// pattern is fixed by the connectivity; TangentAssembler reuses it.
class TangentAssembler {
 public:
  explicit TangentAssembler(const ElasticBody& body);
  // Overwrites the values of `stiffness()` with the tangent at positions_m.
  ElasticEvaluation assemble(const double* positions_m);
  const Eigen::SparseMatrix<double>& stiffness() const { return stiffness_; }
  Eigen::SparseMatrix<double>& stiffness() { return stiffness_; }

 private:
  const ElasticBody* body_;
  Eigen::SparseMatrix<double> stiffness_;
  std::vector<std::int64_t> slot_;  // 144 per tet: index into valuePtr()
};

}  // namespace cellflow::elastic
