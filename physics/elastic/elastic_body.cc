// Construction of an ElasticBody from a tetrahedral mesh and its materials:
// validation of the mesh and the materials, the per-tet reference shape
// matrix B = J^-1, volume and moduli (paper eq. 12), and for the
// nodal-averaged volumetric term the tets around each vertex and the vertex
// volumes. The energy and forces are in elastic_forces.cc, the tangent in
// tangent_assembler.cc.
#include "physics/elastic/elastic_body.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "physics/elastic/elastic_internal.h"

namespace cellflow::elastic {

namespace detail {

// CSR lists of the tets around each vertex.
void vertex_tets(std::span<const std::int32_t> tets, std::size_t num_vertices,
                 std::vector<std::int64_t>& offsets, std::vector<std::int32_t>& incident, int nodes_per_tet) {
  const std::int64_t num_tets = static_cast<std::int64_t>(tets.size()) / nodes_per_tet;
  offsets.assign(num_vertices + 1, 0);
  for (const std::int32_t v : tets) ++offsets[v + 1];
  for (std::size_t v = 0; v < num_vertices; ++v) offsets[v + 1] += offsets[v];
  incident.resize(tets.size());
  std::vector<std::int64_t> next(offsets.begin(), offsets.end() - 1);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    for (int a = 0; a < nodes_per_tet; ++a)
      incident[next[tets[nodes_per_tet * t + a]]++] = static_cast<std::int32_t>(t);
  }
}

}  // namespace detail

using detail::vertex_tets;

void build_lane_blocks(ElasticBody& body) {
  const std::size_t num_tets = body.num_tets();
  const std::size_t num_blocks = (num_tets + kTetBlockLanes - 1) / kTetBlockLanes;
  body.block_b_matrix.assign(num_blocks * 9 * kTetBlockLanes, 0.0);
  body.block_vertices.assign(num_blocks * 4 * kTetBlockLanes, 0);
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::size_t block = t / kTetBlockLanes;
    const std::size_t lane = t % kTetBlockLanes;
    for (int k = 0; k < 9; ++k) {
      body.block_b_matrix[kTetBlockLanes * (9 * block + k) + lane] = body.b_matrix[9 * t + k];
    }
    for (int a = 0; a < 4; ++a) {
      body.block_vertices[kTetBlockLanes * (4 * block + a) + lane] = body.tets[4 * t + a];
    }
  }
  // Float B, and per block M = B B^T (M_00, M_11, M_22, M_01, M_02, M_12) and
  // det B: the inputs of the float neo-Hookean lane (elastic_forces.cc).
  body.float_block_b_matrix.resize(body.block_b_matrix.size());
  for (std::size_t k = 0; k < body.block_b_matrix.size(); ++k) {
    body.float_block_b_matrix[k] = static_cast<float>(body.block_b_matrix[k]);
  }
  body.float_block_neo_hookean.assign(num_blocks * kFloatNeoHookeanRows * kTetBlockLanes, 0.0f);
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::size_t block = t / kTetBlockLanes;
    const std::size_t lane = t % kTetBlockLanes;
    const double* b = body.b_matrix.data() + 9 * t;
    const auto row = [&](int k) -> float& {
      return body.float_block_neo_hookean[kTetBlockLanes * (kFloatNeoHookeanRows * block + k) + lane];
    };
    // M_ac = B_al B_cl
    const auto m = [&](int a, int c) {
      return b[3 * a] * b[3 * c] + b[3 * a + 1] * b[3 * c + 1] + b[3 * a + 2] * b[3 * c + 2];
    };
    row(0) = static_cast<float>(m(0, 0));
    row(1) = static_cast<float>(m(1, 1));
    row(2) = static_cast<float>(m(2, 2));
    row(3) = static_cast<float>(m(0, 1));
    row(4) = static_cast<float>(m(0, 2));
    row(5) = static_cast<float>(m(1, 2));
    row(6) = static_cast<float>(b[0] * (b[4] * b[8] - b[5] * b[7]) + b[1] * (b[5] * b[6] - b[3] * b[8]) +
                                b[2] * (b[3] * b[7] - b[4] * b[6]));
  }
  const auto padded_float = [&](const std::vector<double>& per_tet, std::vector<float>& out) {
    out.assign(num_blocks * kTetBlockLanes, 0.0f);
    for (std::size_t t = 0; t < std::min(num_tets, per_tet.size()); ++t)
      out[t] = static_cast<float>(per_tet[t]);
  };
  padded_float(body.ref_volume_m3, body.float_ref_volume_m3);
  padded_float(body.mu1_pa, body.float_mu1_pa);
  padded_float(body.mu2_pa, body.float_mu2_pa);
  padded_float(body.kappa_pa, body.float_kappa_pa);
}

StatusOr<ElasticBody> make_elastic_body(const mesh::TetMesh& mesh, std::span<const Material> materials,
                                        VolumetricTerm volumetric) {
  const std::size_t num_vertices = mesh.num_vertices();
  const std::size_t num_tets = mesh.num_tets();
  if (mesh.positions_m.size() % 3 != 0 || mesh.tets.size() % 4 != 0) {
    return invalid_argument("mesh: positions_m must hold 3 and tets 4 entries per item");
  }
  if (!mesh.tet_region.empty() && mesh.tet_region.size() != num_tets) {
    return invalid_argument("mesh.tet_region has " + std::to_string(mesh.tet_region.size()) +
                            " entries, expected one per tetrahedron (" + std::to_string(num_tets) + ")");
  }
  std::vector<Moduli> moduli;
  for (std::size_t m = 0; m < materials.size(); ++m) {
    Status status = validate(materials[m], "materials[" + std::to_string(m) + "].");
    if (!status.ok()) return status;
    moduli.push_back(moduli_from(materials[m]));
  }

  // The force loop gathers positions with 32-bit offsets 3 v (elastic_forces.cc).
  if (num_vertices > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max() / 3)) {
    return invalid_argument("mesh: " + std::to_string(num_vertices) + " vertices; at most " +
                            std::to_string(std::numeric_limits<std::int32_t>::max() / 3) + " are supported");
  }
  ElasticBody body;
  body.num_vertices = num_vertices;
  body.tets = mesh.tets;
  body.b_matrix.resize(9 * num_tets);
  body.ref_volume_m3.resize(num_tets);
  body.mu1_pa.resize(num_tets);
  body.mu2_pa.resize(num_tets);
  body.kappa_pa.resize(num_tets);
  const double* x = mesh.positions_m.data();
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = mesh.tets.data() + 4 * t;
    for (int a = 0; a < 4; ++a) {
      if (v[a] < 0 || static_cast<std::size_t>(v[a]) >= num_vertices) {
        return invalid_argument("mesh.tets: tetrahedron " + std::to_string(t) + " names vertex " +
                                std::to_string(v[a]) + ", outside [0, " + std::to_string(num_vertices) + ")");
      }
    }
    const std::size_t region = mesh.tet_region.empty() ? 0 : static_cast<std::size_t>(mesh.tet_region[t]);
    if (region >= moduli.size()) {
      return invalid_argument("materials: tetrahedron " + std::to_string(t) + " is in region " +
                              std::to_string(region) + " but only " + std::to_string(moduli.size()) +
                              " materials were given");
    }
    // J_ik = x_i^k - x_i^4   (paper eq. 12)
    double jac[9];
    for (int i = 0; i < 3; ++i) {
      for (int k = 0; k < 3; ++k) jac[3 * i + k] = x[3 * v[k] + i] - x[3 * v[3] + i];
    }
    const double cof[9] = {jac[4] * jac[8] - jac[5] * jac[7], jac[5] * jac[6] - jac[3] * jac[8],
                           jac[3] * jac[7] - jac[4] * jac[6], jac[2] * jac[7] - jac[1] * jac[8],
                           jac[0] * jac[8] - jac[2] * jac[6], jac[1] * jac[6] - jac[0] * jac[7],
                           jac[1] * jac[5] - jac[2] * jac[4], jac[2] * jac[3] - jac[0] * jac[5],
                           jac[0] * jac[4] - jac[1] * jac[3]};
    const double det = jac[0] * cof[0] + jac[1] * cof[1] + jac[2] * cof[2];
    // V0 = det J / 6 must be positive: vertex order as in paper eq. 11-12
    if (!(det > 0.0)) {
      return Status(StatusCode::kFailedPrecondition,
                    "mesh: tetrahedron " + std::to_string(t) + " (vertices " + std::to_string(v[0]) + " " +
                        std::to_string(v[1]) + " " + std::to_string(v[2]) + " " + std::to_string(v[3]) +
                        ") has reference volume " + std::to_string(det / 6.0) +
                        " m^3; it must be > 0 (det[x1-x4, x2-x4, x3-x4] > 0)");
    }
    // B = J^-1 = cof(J)^T / det J   (paper eq. 12)
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) body.b_matrix[9 * t + 3 * k + l] = cof[3 * l + k] / det;
    }
    body.ref_volume_m3[t] = det / 6.0;
    body.mu1_pa[t] = moduli[region].mu1_pa;
    body.mu2_pa[t] = moduli[region].mu2_pa;
    body.kappa_pa[t] = moduli[region].kappa_pa;
  }
  build_lane_blocks(body);
  body.neo_hookean =
      std::all_of(body.mu2_pa.begin(), body.mu2_pa.end(), [](double mu2) { return mu2 == 0.0; });
  body.volumetric = volumetric;
  if (!mesh.quadratic_tets.empty()) {
    if (volumetric != VolumetricTerm::kPerTet) {
      return invalid_argument(
          "mesh: quadratic tetrahedra evaluate the volumetric term at each quadrature point (kPerTet); "
          "the nodal average is for linear tets");
    }
    if (mesh.quadratic_tets.size() != 10 * num_tets) {
      return invalid_argument("mesh.quadratic_tets has " + std::to_string(mesh.quadratic_tets.size()) +
                              " entries, expected 10 per tetrahedron (" + std::to_string(10 * num_tets) +
                              ")");
    }
    for (std::size_t k = 0; k < mesh.quadratic_tets.size(); ++k) {
      const std::int32_t v = mesh.quadratic_tets[k];
      if (v < 0 || static_cast<std::size_t>(v) >= num_vertices ||
          (k % 10 < 4 && v != mesh.tets[4 * (k / 10) + k % 10])) {
        return invalid_argument("mesh.quadratic_tets: tetrahedron " + std::to_string(k / 10) + " node " +
                                std::to_string(k % 10) + " = " + std::to_string(v) +
                                " is outside the vertices or not the corner of mesh.tets");
      }
    }
    body.element = Element::kQuadraticTet;
    body.quadratic_tets = mesh.quadratic_tets;
    if (Status s = detail::build_quadratic_tets(body, x); !s.ok()) return s;
    return body;
  }
  if (volumetric == VolumetricTerm::kNodalAverage) {
    vertex_tets(body.tets, num_vertices, body.vertex_tet_offsets, body.vertex_tets);
    body.vertex_volume_m3.assign(num_vertices, 0.0);
    body.vertex_bulk_volume_j.assign(num_vertices, 0.0);
    for (std::size_t t = 0; t < num_tets; ++t) {
      for (int a = 0; a < 4; ++a) {
        const std::int32_t v = body.tets[4 * t + a];
        body.vertex_volume_m3[v] += 0.25 * body.ref_volume_m3[t];
        body.vertex_bulk_volume_j[v] += 0.25 * body.kappa_pa[t] * body.ref_volume_m3[t];
      }
    }
  }
  return body;
}

}  // namespace cellflow::elastic
