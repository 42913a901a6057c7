// The quadratic 10-node tetrahedron (Element::kQuadraticTet): its reference
// data, energy and nodal forces, smallest volume ratio and tangent. The
// material is the linear tet's (tet_kernel.h: stress_at_gradient,
// stress_derivative) evaluated at each quadrature point, so the two elements
// share the Mooney-Rivlin law of paper eq. 5-8 and its derivatives.
//
// Shape functions in the barycentric coordinates L_a of the corners, with
// L_0..L_2 = s_1..s_3 and L_3 = 1 - s_1 - s_2 - s_3 (corner 3 the origin of
// the element coordinates, as for the linear tet, paper eq. 11):
//   N_a = L_a (2 L_a - 1) (corners),  N_ab = 4 L_a L_b (mid-edge nodes).
// Per quadrature point q: dX/ds = sum_n X_n (x) dN_n/ds, G_qn = dN_n/dX,
//   F = sum_n y_n (x) G_qn,  E = sum_q w_q |det dX/ds| U(F_q)   (paper eq. 5, 9)
//   f_n = -sum_q w_q |det dX/ds| P(F_q) G_qn   (P = dU/dF, paper section 3.2)
//   K_(n i),(m j) = sum_q w_q |det dX/ds| G_qn,l d^2U/dF_il dF_jk G_qm,k.
// The 4-point rule of degree 2 integrates the linear-elastic stiffness of the
// quadratic tet exactly (its strains are linear), as C3D10's does.
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/elastic/elastic_internal.h"
#include "physics/elastic/tet_kernel.h"
#include "physics/mesh/quadratic_tets.h"

namespace cellflow::elastic {

namespace {

constexpr int kNodes = 10;
constexpr int kPoints = kQuadraticTetPoints;

// 4-point Gauss rule on the tetrahedron (degree 2): barycentric (a, b, b, b)
// and permutations, a = (5 + 3 sqrt 5) / 20, b = (5 - sqrt 5) / 20, weight
// 1/4 of the volume (1/24 of the unit tet in s).
constexpr double kPointA = 0.5854101966249685;
constexpr double kPointB = 0.1381966011250105;
constexpr double kPointWeight = 1.0 / 24.0;

// dN_n/ds_k (10 x 3, row-major) at barycentric coordinates l[4].
void shape_derivatives(const double* l, double* dn) {
  // dL_a/ds_k: delta_ak for a = 0..2, -1 for a = 3
  const auto dl = [](int a, int k) { return a == 3 ? -1.0 : (a == k ? 1.0 : 0.0); };
  for (int k = 0; k < 3; ++k) {
    // corners: dN_a/ds = (4 L_a - 1) dL_a/ds
    for (int a = 0; a < 4; ++a) dn[3 * a + k] = (4.0 * l[a] - 1.0) * dl(a, k);
    // mid-edge nodes: dN_ab/ds = 4 (L_b dL_a/ds + L_a dL_b/ds)
    for (int e = 0; e < 6; ++e) {
      const int a = mesh::kQuadraticTetEdges[e][0], b = mesh::kQuadraticTetEdges[e][1];
      dn[3 * (4 + e) + k] = 4.0 * (l[b] * dl(a, k) + l[a] * dl(b, k));
    }
  }
}

void point_coordinates(int q, double* l) {
  for (int a = 0; a < 4; ++a) l[a] = a == q ? kPointA : kPointB;
}

kernel::TetParams point_params(const ElasticBody& body, std::int64_t t) {
  return {nullptr, body.ref_volume_m3[t], body.mu1_pa[t], body.mu2_pa[t], body.kappa_pa[t]};
}

// F_il = sum_n y_n,i G_n,l at one quadrature point, with its cofactor and J.
void point_gradient(const double* y, const std::int32_t* nodes, const double* g, kernel::TetStress& s) {
  for (int k = 0; k < 9; ++k) s.f[k] = 0.0;
  for (int n = 0; n < kNodes; ++n) {
    const double* yn = y + 3 * static_cast<std::int64_t>(nodes[n]);
    const double* gn = g + 3 * n;
    for (int i = 0; i < 3; ++i) {
      for (int l = 0; l < 3; ++l) s.f[3 * i + l] += yn[i] * gn[l];
    }
  }
  s.det_f[0] = kernel::cofactor_of_gradient(s.f, s.cof);
}

template <bool kMooneyRivlin>
ElasticEvaluation forces_impl(const ElasticBody& body, const double* y, double* forces, std::int64_t begin,
                              std::int64_t end) {
  ElasticEvaluation result;
  for (std::int64_t t = begin; t < end; ++t) {
    const std::int32_t* nodes = body.quadratic_tets.data() + kNodes * t;
    const kernel::TetParams p = point_params(body, t);
    for (int q = 0; q < kPoints; ++q) {
      const double* g = body.quadrature_gradients.data() + 3 * kNodes * (kPoints * t + q);
      const double w = body.quadrature_weights_m3[kPoints * t + q];
      kernel::TetStress s;
      point_gradient(y, nodes, g, s);
      if (!kernel::stress_at_gradient<kMooneyRivlin>(p, s)) {
        if (result.first_inverted_tet < 0) result.first_inverted_tet = t;
        continue;
      }
      result.energy_j += w * s.energy_density[0];
      if (forces == nullptr) continue;
      // f_n,i -= w P_il G_n,l
      for (int n = 0; n < kNodes; ++n) {
        double* fn = forces + 3 * static_cast<std::int64_t>(nodes[n]);
        const double* gn = g + 3 * n;
        for (int i = 0; i < 3; ++i) {
          fn[i] -= w * (s.stress[3 * i] * gn[0] + s.stress[3 * i + 1] * gn[1] + s.stress[3 * i + 2] * gn[2]);
        }
      }
    }
  }
  return result;
}

}  // namespace

namespace detail {

Status build_quadratic_tets(ElasticBody& body, const double* x) {
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  body.quadrature_gradients.assign(3 * kNodes * kPoints * num_tets, 0.0);
  body.quadrature_weights_m3.assign(kPoints * num_tets, 0.0);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    const std::int32_t* nodes = body.quadratic_tets.data() + kNodes * t;
    for (int q = 0; q < kPoints; ++q) {
      double l[4], dn[3 * kNodes];
      point_coordinates(q, l);
      shape_derivatives(l, dn);
      // J_ik = dX_i/ds_k = sum_n X_n,i dN_n/ds_k
      double jac[9] = {};
      for (int n = 0; n < kNodes; ++n) {
        const double* xn = x + 3 * static_cast<std::int64_t>(nodes[n]);
        for (int i = 0; i < 3; ++i) {
          for (int k = 0; k < 3; ++k) jac[3 * i + k] += xn[i] * dn[3 * n + k];
        }
      }
      double cof[9];
      const double det = kernel::cofactor_of_gradient(jac, cof);
      if (!(det > 0.0)) {
        return Status(StatusCode::kFailedPrecondition,
                      "mesh: quadratic tetrahedron " + std::to_string(t) + " has det dX/ds = " +
                          std::to_string(det) + " at quadrature point " + std::to_string(q) +
                          "; it must be > 0 (corner order as in paper eq. 11-12, mid-edge nodes near the "
                          "edges' midpoints)");
      }
      // G_n,l = dN_n/ds_k (J^-1)_kl, J^-1 = cof(J)^T / det J
      double* g = body.quadrature_gradients.data() + 3 * kNodes * (kPoints * t + q);
      for (int n = 0; n < kNodes; ++n) {
        for (int l2 = 0; l2 < 3; ++l2) {
          double sum = 0.0;
          for (int k = 0; k < 3; ++k) sum += dn[3 * n + k] * cof[3 * l2 + k];
          g[3 * n + l2] = sum / det;
        }
      }
      body.quadrature_weights_m3[kPoints * t + q] = kPointWeight * det;
    }
  }
  return {};
}

ElasticEvaluation quadratic_forces(const ElasticBody& body, const double* y, double* forces,
                                   std::int64_t begin, std::int64_t end) {
  if (body.neo_hookean) return forces_impl<false>(body, y, forces, begin, end);
  return forces_impl<true>(body, y, forces, begin, end);
}

VolumeRatioMinimum quadratic_min_volume_ratio(const ElasticBody& body, const double* y) {
  VolumeRatioMinimum minimum;
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(body.num_tets()); ++t) {
    const std::int32_t* nodes = body.quadratic_tets.data() + kNodes * t;
    for (int q = 0; q < kPoints; ++q) {
      kernel::TetStress s;
      point_gradient(y, nodes, body.quadrature_gradients.data() + 3 * kNodes * (kPoints * t + q), s);
      // J = det F at the point: the local volume ratio
      if (s.det_f[0] < minimum.volume_ratio) minimum = {s.det_f[0], t};
    }
  }
  return minimum;
}

}  // namespace detail

template <bool kMooneyRivlin>
ElasticEvaluation TangentAssembler::assemble_quadratic(const double* y, double* forces) {
  const ElasticBody& body = *body_;
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  double* values = stiffness_.valuePtr();
  std::fill_n(values, stiffness_.nonZeros(), 0.0);
  ElasticEvaluation result;
  constexpr int kDofs = 3 * kNodes;
  for (std::int64_t t = 0; t < num_tets; ++t) {
    const std::int32_t* nodes = body.quadratic_tets.data() + kNodes * t;
    const kernel::TetParams p = point_params(body, t);
    double block[kDofs * kDofs] = {};
    bool inverted = false;
    for (int q = 0; q < kPoints && !inverted; ++q) {
      const double* g = body.quadrature_gradients.data() + kDofs * (kPoints * t + q);
      const double w = body.quadrature_weights_m3[kPoints * t + q];
      kernel::TetStress s;
      point_gradient(y, nodes, g, s);
      if (!kernel::stress_at_gradient<kMooneyRivlin>(p, s)) {
        inverted = true;
        break;
      }
      result.energy_j += w * s.energy_density[0];
      if (forces != nullptr) {
        for (int n = 0; n < kNodes; ++n) {
          double* fn = forces + 3 * static_cast<std::int64_t>(nodes[n]);
          const double* gn = g + 3 * n;
          for (int i = 0; i < 3; ++i) {
            fn[i] -=
                w * (s.stress[3 * i] * gn[0] + s.stress[3 * i + 1] * gn[1] + s.stress[3 * i + 2] * gn[2]);
          }
        }
      }
      double d2u[81];
      kernel::stress_derivative<kMooneyRivlin>(p, s, d2u);
      // half[(i l), (m j)] = w sum_k d2u[(i l), (j k)] G_m,k
      double half[9 * kDofs];
      for (int r = 0; r < 9; ++r) {
        for (int m = 0; m < kNodes; ++m) {
          const double* gm = g + 3 * m;
          for (int j = 0; j < 3; ++j) {
            const double* row = d2u + 9 * r + 3 * j;
            half[kDofs * r + 3 * m + j] = w * (row[0] * gm[0] + row[1] * gm[1] + row[2] * gm[2]);
          }
        }
      }
      // block[(n i), (m j)] += sum_l G_n,l half[(i l), (m j)]
      for (int n = 0; n < kNodes; ++n) {
        const double* gn = g + 3 * n;
        for (int i = 0; i < 3; ++i) {
          double* out = block + kDofs * (3 * n + i);
          const double* h0 = half + kDofs * (3 * i);
          const double* h1 = h0 + kDofs;
          const double* h2 = h1 + kDofs;
          for (int c = 0; c < kDofs; ++c) out[c] += gn[0] * h0[c] + gn[1] * h1[c] + gn[2] * h2[c];
        }
      }
    }
    if (inverted) {
      if (result.first_inverted_tet < 0) result.first_inverted_tet = t;
      continue;
    }
    // Scatter: entry (row 3 v_n + i, column 3 v_m + j) at slot_[3 (100 t + 10 n + m) + j] + i.
    const std::int64_t* slots = slot_.data() + 3 * kNodes * kNodes * t;
    for (int n = 0; n < kNodes; ++n) {
      for (int m = 0; m < kNodes; ++m) {
        for (int j = 0; j < 3; ++j) {
          double* column = values + slots[3 * (kNodes * n + m) + j];
          for (int i = 0; i < 3; ++i) column[i] += block[kDofs * (3 * n + i) + 3 * m + j];
        }
      }
    }
  }
  return result;
}

template ElasticEvaluation TangentAssembler::assemble_quadratic<false>(const double*, double*);
template ElasticEvaluation TangentAssembler::assemble_quadratic<true>(const double*, double*);

}  // namespace cellflow::elastic
