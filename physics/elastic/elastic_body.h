// Vertex forces of a tetrahedral Mooney-Rivlin body:
//   f_i^a = -V0 dU/du_i^a   (paper eq. 9-10, derivative table of section 3.2)
// with F = 1 + A B, A_ik = u_i^k - u_i^4, B = J^-1 of the reference tetrahedron
// (paper eq. 11-12). B and V0 are computed once per tetrahedron.
#pragma once

#include <Eigen/SparseCore>
#include <cstdint>
#include <span>
#include <vector>

#include "physics/core/status.h"
#include "physics/elastic/material.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::elastic {

// Precomputed reference data, one entry per tetrahedron (structure of arrays).
struct ElasticBody {
  std::vector<std::int32_t> tets;                // 4 per tet, copied from the mesh
  std::vector<double> b_matrix;                  // 9 per tet, row-major B = J^-1
  std::vector<double> ref_volume_m3;             // V0 per tet
  std::vector<double> mu1_pa, mu2_pa, kappa_pa;  // per tet, from its region's material
  bool neo_hookean = true;                       // every mu2 == 0: the K-term work is skipped
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

// The serial building block of add_elastic_forces: energy and forces of the
// tets [begin_tet, end_tet) only, on the calling thread.
ElasticEvaluation add_elastic_forces_of_range(const ElasticBody& body, const double* positions_m,
                                              double* forces_n, std::int64_t begin_tet, std::int64_t end_tet);

// Energy only, same arithmetic as add_elastic_forces.
ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m);
// As above with an OpenMP thread count (<= 0: the OpenMP default).
ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m, int threads);

// Groups of `group_size` consecutive tetrahedra (group g = tets [g s, g s + s))
// coloured such that no two groups of one colour share a vertex (greedy, in
// order): a colour can be scattered in parallel without races. Groups of
// colour c are order[offsets[c] .. offsets[c + 1]). With group_size 1 the
// groups are single tets; larger groups give fewer colours (fewer barriers)
// and keep each thread streaming through consecutive tets.
struct TetColouring {
  std::int64_t group_size = 1;
  std::vector<std::int32_t> order;
  std::vector<std::int64_t> offsets;
  std::size_t num_colours() const { return offsets.empty() ? 0 : offsets.size() - 1; }
};
TetColouring colour_tets(std::span<const std::int32_t> tets, std::size_t num_vertices,
                         std::int64_t group_size = 1);

// Tangent stiffness K = d^2 E / dy dy (3 nv x 3 nv, symmetric) at y. The
// pattern is fixed by the connectivity; TangentAssembler reuses it.
class TangentAssembler {
 public:
  // `body` must outlive the assembler. The matrix stores both triangles.
  explicit TangentAssembler(const ElasticBody& body);
  // Overwrites the values of `stiffness()` with the tangent at positions_m.
  ElasticEvaluation assemble(const double* positions_m);
  // Same pass, and also adds the elastic forces (as add_elastic_forces) into forces_n.
  ElasticEvaluation assemble(const double* positions_m, double* forces_n);
  const Eigen::SparseMatrix<double>& stiffness() const { return stiffness_; }
  Eigen::SparseMatrix<double>& stiffness() { return stiffness_; }
  // OpenMP threads for assemble(); <= 0 (the default) uses the OpenMP default.
  void set_threads(int threads) { threads_ = threads; }

 private:
  template <bool kMooneyRivlin>
  ElasticEvaluation assemble_impl(const double* positions_m, double* forces_n);

  const ElasticBody* body_;
  Eigen::SparseMatrix<double> stiffness_;
  // 48 per tet: slot_[3 (16 t + 4 a + b) + j] is the index into valuePtr() of
  // the entry (row 3 v_a, column 3 v_b + j) for local vertices a, b of tet t;
  // rows 3 v_a + 1 and + 2 follow it (a column holds a vertex's rows together).
  std::vector<std::int64_t> slot_;
  TetColouring colouring_;            // race-free parallel scatter, groups of consecutive tets
  std::vector<double> group_energy_;  // per colouring group, summed in order
  int threads_ = 0;
};

}  // namespace cellflow::elastic
