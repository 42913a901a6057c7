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
#include "physics/mesh/tet_colouring.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::elastic {

// How the volumetric term kappa/2 (J - 1)^2 of paper eq. (5) is evaluated.
enum class VolumetricTerm {
  // Per tetrahedron with its own J, as in the paper.
  kPerTet,
  // Per vertex with J averaged over the tetrahedra around it (average nodal
  // pressure, Bonet & Burton 1998):
  //   sum_a (kappa V)_a / 2 (Jbar_a - 1)^2,  V_a = sum_{t at a} V0_t / 4,
  //   (kappa V)_a = sum_{t at a} kappa_t V0_t / 4,  Jbar_a = sum_{t at a} V0_t J_t / (4 V_a).
  // A linear tetrahedron with its own J locks as nu -> 1/2: a mesh has about
  // five tets per vertex, each a volume constraint, against three degrees of
  // freedom per vertex. One constraint per vertex leaves the shape free.
  // Equal to kPerTet for any homogeneous deformation; the isochoric terms
  // (mu1, mu2) stay per tet.
  kNodalAverage,
};

// The finite element of the body.
enum class Element {
  // 4-node tetrahedron, one F per tet (paper eq. 11-12).
  kLinearTet,
  // 10-node tetrahedron (mesh::TetMesh::quadratic_tets, VTK node order):
  // quadratic shape functions N_a = L_a (2 L_a - 1) at the corners and
  // N_ab = 4 L_a L_b at the mid-edge nodes (L the barycentric coordinates),
  // the energy of eq. 5 integrated with the 4-point Gauss rule of degree 2
  // (physics/elastic/quadratic_tet.cc). F, and so J, vary inside the tet:
  // its strain is linear where the linear tet's is constant, and it bends.
  // The volumetric term is evaluated at each quadrature point (kPerTet only).
  kQuadraticTet,
};

// Quadrature points per quadratic tet.
constexpr int kQuadraticTetPoints = 4;

// Tets per lane block of the force loop (elastic_forces.cc) and of the
// lane-blocked copies in ElasticBody.
constexpr int kTetBlockLanes = 16;
// Rows of ElasticBody::float_block_neo_hookean per block.
constexpr int kFloatNeoHookeanRows = 7;

// Precomputed reference data, one entry per tetrahedron (structure of arrays).
struct ElasticBody {
  std::vector<std::int32_t> tets;                // 4 per tet, copied from the mesh
  std::vector<double> b_matrix;                  // 9 per tet, row-major B = J^-1
  std::vector<double> ref_volume_m3;             // V0 per tet
  std::vector<double> mu1_pa, mu2_pa, kappa_pa;  // per tet, from its region's material
  // Lane-blocked copies for the force loop, blocks of kTetBlockLanes tets
  // (the last padded with zeros): tet l of block n has B_k at
  // block_b_matrix[kTetBlockLanes (9 n + k) + l] and local vertex a at
  // block_vertices[kTetBlockLanes (4 n + a) + l]. The loop then reads B with
  // vector loads instead of gathering it tet by tet (88 bytes per tet).
  std::vector<double> block_b_matrix;
  std::vector<std::int32_t> block_vertices;
  // Single-precision copies for the float force loop (ForcePrecision::kFloat):
  // B in the block_b_matrix layout; kFloatNeoHookeanRows rows of
  // kTetBlockLanes per block of M = B B^T (M_00, M_11, M_22, M_01, M_02,
  // M_12) and det B, which the neo-Hookean lane reads instead of B; V0 and the
  // moduli per tet padded with zeros to whole blocks (80 bytes per tet).
  std::vector<float> float_block_b_matrix;
  std::vector<float> float_block_neo_hookean;
  std::vector<float> float_ref_volume_m3, float_mu1_pa, float_mu2_pa, float_kappa_pa;
  bool neo_hookean = true;  // every mu2 == 0: the K-term work is skipped
  std::size_t num_vertices = 0;
  VolumetricTerm volumetric = VolumetricTerm::kPerTet;
  // kNodalAverage only: V_a and (kappa V)_a per vertex, and the tetrahedra
  // around each vertex (tets vertex_tets[vertex_tet_offsets[a] .. [a + 1]]).
  std::vector<double> vertex_volume_m3, vertex_bulk_volume_j;
  std::vector<std::int64_t> vertex_tet_offsets;
  std::vector<std::int32_t> vertex_tets;

  // Element::kQuadraticTet only (the arrays above then hold the corner tets:
  // V0 of the straight-sided tet, the moduli per tet): the 10 nodes per tet,
  // and per tet and quadrature point q the reference gradients
  // G_qa = dN_a/dX (30 = 10 nodes x 3, row-major, at
  // quadrature_gradients[30 (kQuadraticTetPoints t + q)]) and the weights
  // w_q |det dX/dxi| (sum over q: the curved tet's volume).
  Element element = Element::kLinearTet;
  std::vector<std::int32_t> quadratic_tets;
  std::vector<double> quadrature_gradients, quadrature_weights_m3;

  std::size_t num_tets() const { return ref_volume_m3.size(); }
  bool quadratic() const { return element == Element::kQuadraticTet; }
};

// (Re)builds block_b_matrix, block_vertices and the float copies from tets,
// b_matrix, ref_volume_m3 and the moduli; for a
// body assembled by hand (make_elastic_body calls it). The force loop builds a
// temporary copy of a body without them, which is slow.
void build_lane_blocks(ElasticBody& body);

// Fails (kFailedPrecondition) on a tetrahedron with non-positive reference
// volume, naming its index. `materials` is indexed by mesh::Region. A mesh
// with quadratic_tets gives an Element::kQuadraticTet body (kPerTet only;
// fails on a quadrature point with non-positive det dX/dxi).
// Every function below handles both elements; the quadratic one runs the
// double loop on one thread (no lanes, no float copy: ForcePrecision and
// TetSimd are ignored).
StatusOr<ElasticBody> make_elastic_body(const mesh::TetMesh& mesh, std::span<const Material> materials,
                                        VolumetricTerm volumetric = VolumetricTerm::kPerTet);

struct ElasticEvaluation {
  double energy_j = 0.0;
  std::int64_t first_inverted_tet = -1;  // >= 0 if some J <= 0 (forces then invalid)
};

// Adds the elastic forces at deformed positions y (3 per vertex, metres) into
// forces_n and returns the elastic energy sum V0 U. Energy and forces come from
// one code path. `threads` <= 0 uses the OpenMP default. Each thread scatters
// into its own padded accumulator (4 doubles per vertex, kept per thread and
// reused by later calls): the scatter allocates nothing once it has run.
ElasticEvaluation add_elastic_forces(const ElasticBody& body, const double* positions_m, double* forces_n,
                                     int threads = 0);

// Arithmetic of the force loop. kDouble everywhere by default. kFloat (the
// flow scenes' option, ShearFlowNumerics::elastic_single_precision): the
// positions relative to the centre of their bounding box (so that F keeps its
// digits wherever the body sits), the per-tet stages and the force sums per
// vertex in float, 16 lanes to two AVX2 registers instead of four; energy
// summed and forces returned in double. Forces agree with kDouble to
// 1e-7 (kappa / mu) / strain of the largest vertex force, set by the bulk
// term's J - 1 (tests/elastic/float_forces_test.cc: 2.7e-4 at strain 0.05,
// nu 0.48; 2e-5 at large strain); the quasi-static solver keeps kDouble (its
// Newton convergence needs the gradient to round-off). Every SIMD level gives
// the same bits in either precision.
enum class ForcePrecision { kDouble, kFloat };
ElasticEvaluation add_elastic_forces(const ElasticBody& body, const double* positions_m, double* forces_n,
                                     int threads, ForcePrecision precision);

// SIMD level of the force and energy loops (elastic_forces.cc): one copy per
// level is built and the best the CPU has is used (kAuto). Every level gives
// the same bits; the others exist for tests and benchmarks.
enum class TetSimd { kAuto, kGeneric, kAvx2, kAvx512 };
TetSimd best_tet_simd();
bool tet_simd_supported(TetSimd simd);
const char* tet_simd_name(TetSimd simd);

// The serial building block of add_elastic_forces: energy and forces of the
// tets [begin_tet, end_tet) only, on the calling thread, at SIMD level `simd`
// (one the CPU lacks, tet_simd_supported, runs the generic copy).
ElasticEvaluation add_elastic_forces_of_range(const ElasticBody& body, const double* positions_m,
                                              double* forces_n, std::int64_t begin_tet, std::int64_t end_tet,
                                              TetSimd simd = TetSimd::kAuto);
// As above in precision `precision` (kFloat: the float loop, positions
// relative to the centre of their bounding box as add_elastic_forces does).
ElasticEvaluation add_elastic_forces_of_range(const ElasticBody& body, const double* positions_m,
                                              double* forces_n, std::int64_t begin_tet, std::int64_t end_tet,
                                              TetSimd simd, ForcePrecision precision);

// Energy only, same arithmetic as add_elastic_forces.
ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m);
// As above with an OpenMP thread count (<= 0: the OpenMP default).
ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m, int threads);

// The smallest J = v / V0 over the tetrahedra at positions_m and its tet.
struct VolumeRatioMinimum {
  double volume_ratio = 1.0;
  std::int64_t tet = -1;
};
VolumeRatioMinimum min_volume_ratio(const ElasticBody& body, const double* positions_m);

// Tangent stiffness K = d^2 E / dy dy (3 nv x 3 nv, symmetric) at y. The
// pattern is fixed by the connectivity; TangentAssembler reuses it.
//
// With VolumetricTerm::kNodalAverage K has a second part,
//   K = stiffness() + G^T C G,  rows g_a = dv_a/dy of G, C = diag (kappa V)_a / V_a^2,
// the Gauss-Newton part of the vertex volumetric energies (their pressure part
// p dcof/dF is in the tet blocks of stiffness()). Each g_a couples all the
// vertices around a; assembled, it would triple the nonzeros of K. It is
// applied instead (add_volumetric_product, about the cost of the sparse
// product) and its diagonal 3x3 blocks are available for preconditioners.
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
  // True for kNodalAverage: K has the applied part G^T C G.
  bool has_volumetric_operator() const { return !vertex_coefficient_.empty(); }
  // out += G^T C G x at the last assembled state (no-op without the operator).
  void add_volumetric_product(const double* x, double* out) const;
  // The two passes of add_volumetric_product over a vertex range [begin, end),
  // for a caller that runs its own team (one parallel region per linear
  // solve): z[a] = C_a g_a . x for a in the range (reads x on a's patch), then
  // out_b += sum_a z_a g_a[b] for b in the range (reads z on b's patch, so
  // every z the scatter reads must have been written first).
  void volumetric_gather(const double* x, std::int64_t begin, std::int64_t end, double* z) const;
  void add_volumetric_scatter(const double* z, std::int64_t begin, std::int64_t end, double* out) const;
  // Entries of row a of G (the patch of a: a and its neighbours); 0 without the operator.
  std::int64_t volumetric_row_length(std::size_t a) const {
    return has_volumetric_operator() ? patch_offsets_[a + 1] - patch_offsets_[a] : 0;
  }
  // G in the layout of the patches (for a caller that fuses the gather into
  // its own pass over the same neighbour lists): row a has the entries
  // [offsets[a], offsets[a + 1]) of patches, g_a[patches[k]] at rows + 3 k,
  // and C_a at coefficients[a]. Empty without the operator.
  std::span<const std::int64_t> volumetric_patch_offsets() const { return patch_offsets_; }
  std::span<const std::int32_t> volumetric_patches() const { return patches_; }
  const double* volumetric_rows() const { return g_rows_.data(); }
  const double* volumetric_coefficients() const { return vertex_coefficient_.data(); }
  // blocks[9 v + 3 i + j] += (G^T C G)_(3v+i),(3v+j): its diagonal 3x3 blocks.
  void add_volumetric_diagonal_blocks(double* blocks) const;
  // out = K x with both parts (tests and small problems).
  void multiply(const double* x, double* out) const;
  // OpenMP threads for assemble(); <= 0 (the default) uses the OpenMP default.
  void set_threads(int threads) { threads_ = threads; }

 private:
  template <bool kMooneyRivlin>
  ElasticEvaluation assemble_impl(const double* positions_m, double* forces_n);
  // Element::kQuadraticTet (quadratic_tet.cc): serial, 30x30 blocks.
  template <bool kMooneyRivlin>
  ElasticEvaluation assemble_quadratic(const double* positions_m, double* forces_n);
  // kNodalAverage: the rows g_a of G and C at positions_m, on `team` threads.
  void update_volumetric_operator(const double* positions_m, int team);

  const ElasticBody* body_;
  Eigen::SparseMatrix<double> stiffness_;
  // 3 n^2 per tet (n = 4 nodes, 10 quadratic): slot_[3 (n^2 t + n a + b) + j] is the index into valuePtr() of
  // the entry (row 3 v_a, column 3 v_b + j) for local nodes a, b of tet t;
  // rows 3 v_a + 1 and + 2 follow it (a column holds a vertex's rows together).
  std::vector<std::int64_t> slot_;
  // kNodalAverage: G by rows, row a over the patch of a (a and its
  // neighbours, patches_[patch_offsets_[a] ..]), 3 values per patch vertex at
  // the same offsets (g_rows_[3 k + i]); the patch positions of the vertices
  // of the tets around a (4 per entry of body.vertex_tets); for every row
  // entry k of vertex w = patches_[k], the entry of the row of w that holds
  // a (the patch relation is symmetric), so G^T rows are G rows read across.
  std::vector<std::int64_t> patch_offsets_;
  std::vector<std::int32_t> patches_, patch_local_;
  std::vector<std::int64_t> mirror_entry_;
  std::vector<double> g_rows_, vertex_coefficient_;
  // G^T by rows, in the layout of g_rows_: entry k of row b (a = patches_[k])
  // holds g_a[b], copied from g_rows_[3 mirror_entry_[k]] once per assembly so
  // that the scatter of every product streams it instead of gathering.
  std::vector<double> g_columns_;
  mutable std::vector<double> vertex_scratch_;
  std::vector<double> tet_pressure_;  // kNodalAverage scratch: mean nodal pressure per tet
  mesh::TetColouring colouring_;      // race-free parallel scatter, groups of consecutive tets
  std::vector<double> group_energy_;  // per colouring group, summed in order
  int threads_ = 0;
};

}  // namespace cellflow::elastic
