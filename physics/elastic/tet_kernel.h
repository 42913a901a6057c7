// Per-tetrahedron kernels of the Mooney-Rivlin body. Energy, vertex forces and
// the 12x12 tangent block all come from the same stages (deformation_gradient,
// inverse_cube_root, stress_from_gradient, then forces_from_stress and
// stress_derivative), so the energy, its gradient and its Hessian cannot drift
// apart. The force loop (elastic_forces.cc) runs the stages over blocks of tets
// (with the stress pre-scaled by -V0 and forces_from_scaled_stress); the
// tangent runs them tet by tet (tet_stress, tet_tangent).
//
// Local vertex a = 0..3 of a tetrahedron is the paper's vertex a+1; local vertex
// 3 (the paper's vertex 4) is the origin of the element coordinates. With the
// deformed edge matrix D_ik = y_i^k - y_i^4 (k = 1..3) the deformation gradient
// is F = 1 + A B = D B, because A = D - J and J B = 1 (paper eq. 11-12).
//
// All 3x3 tensors are row-major T[9]: T[3 * i + l] = T_il. The stages of the
// force loop are templates on the floating-point type T: double everywhere,
// float for the single-precision force loop of the flow scenes
// (ForcePrecision::kFloat, elastic_body.h). Every constant is written as T(c),
// so the double instances are the arithmetic they were before.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>

namespace cellflow::elastic::kernel {

// x^-1/3 for a normal, finite x > 0, to within 1 ulp (max 0.87 ulp measured
// over 1e7 samples in [1e-13, 1e13]), branch-free and without division: the
// exponent divided by -3 on the high 32 bits of the bit pattern (within 3.5 %;
// 32-bit so that the lane loops of elastic_forces.cc vectorise it, a 64-bit
// division by 3 has no SIMD form), then two steps of the series
// (1 + d)^-1/3 = 1 - d/3 + 2/9 d^2 - 14/81 d^3 + 35/243 d^4 with
// d = x y^3 - 1 (errors 1.4e-6, then 1e-17). Replaces std::cbrt and the
// division by J, which took half of the force kernel's time.
inline __attribute__((always_inline)) double inverse_cube_root(double x) {
  const std::uint32_t high = static_cast<std::uint32_t>(std::bit_cast<std::uint64_t>(x) >> 32);
  double y = std::bit_cast<double>(static_cast<std::uint64_t>(0x553ef0a0u - high / 3u) << 32);
  double d = x * y * y * y - 1.0;
  y *= 1.0 + d * (-1.0 / 3.0 + d * (2.0 / 9.0 + d * (-14.0 / 81.0 + d * (35.0 / 243.0))));
  d = x * y * y * y - 1.0;
  return y - y * d * (1.0 / 3.0 - d * (2.0 / 9.0));
}

// The float x^-1/3 of the single-precision force loop, the same scheme on
// the 32-bit pattern (initial guess within 3.4 %, the double constant with
// three more mantissa bits): after the two steps within 2 ulp of float
// (tests/elastic/float_forces_test.cc). The products and the series are
// grouped for a short dependency chain (x y and y^2 side by side, the
// series in Estrin's form): in the float loop one chain spans the 8 lanes
// of an AVX2 register, and its latency, not the throughput, bounds the stage.
inline __attribute__((always_inline)) float inverse_cube_root(float x) {
  // bits / 3 through float (bits < 2^31, the quotient within 2^7 of the
  // integer one: 2e-5 of the guess, against its 3.4 %): a conversion and a
  // product instead of the integer division's multiply-high sequence.
  const std::int32_t bits = std::bit_cast<std::int32_t>(x);
  const std::int32_t third = static_cast<std::int32_t>(static_cast<float>(bits) * (1.0f / 3.0f));
  float y = std::bit_cast<float>(0x54a22fab - third);
  float d = (x * y) * (y * y) - 1.0f;
  const float d2 = d * d;
  y *= (1.0f - (1.0f / 3.0f) * d) + d2 * ((2.0f / 9.0f - (14.0f / 81.0f) * d) + d2 * (35.0f / 243.0f));
  d = (x * y) * (y * y) - 1.0f;
  return y - (y * d) * (1.0f / 3.0f - d * (2.0f / 9.0f));
}

// x for x > 0, and (to round-off) 1 for x <= 0; NaN stays NaN: the argument
// of inverse_cube_root for a lane that may hold an inverted tet, whose result
// is discarded. Arithmetic rather than a select: GCC turns the select into a
// branch, and the bit-mask blend has no SSE2 form, either of which stops the
// lane loop of elastic_forces.cc from vectorising. For x > 0 the added term
// is a signed zero, so x comes back exactly.
template <class T>
inline __attribute__((always_inline)) T one_if_not_positive(T x) {
  return x + static_cast<T>(x <= T(0)) * (T(1) - x);
}

// Per-tet material and geometry, read from an ElasticBody.
struct TetParams {
  const double* b_matrix;  // 9, B = J^-1 of the reference tetrahedron
  double ref_volume_m3;
  double mu1_pa, mu2_pa, kappa_pa;
  // Pressure p added as p cof(F) to the stress (and p dcof/dF to its
  // derivative). The nodal-averaged volumetric term sets kappa_pa = 0 and
  // passes the mean of the tet's nodal pressures here; otherwise 0.
  double pressure_pa = 0.0;
};

// Everything the forces and the tangent need at one deformation gradient, for
// kLanes tets side by side (structure of arrays: component k of lane l at
// [kLanes * k + l]). The tangent uses one lane (TetStress); the force loop
// (elastic_forces.cc) a block of lanes, so that its lane loop over the stages
// below vectorises across tets.
template <int kLanes, class T = double>
struct TetStressLanes {
  // Cache-line rows for a lane block; one tet keeps the plain layout.
  static constexpr std::size_t kAlign = kLanes > 1 ? 64 : alignof(T);
  alignas(kAlign) T f[9 * kLanes];        // deformation gradient F
  alignas(kAlign) T cof[9 * kLanes];      // cofactor J F^-T = dJ/dF
  alignas(kAlign) T fc[9 * kLanes];       // F C with C = F^T F (Mooney-Rivlin only)
  alignas(kAlign) T c[9 * kLanes];        // C = F^T F (Mooney-Rivlin only)
  alignas(kAlign) T stress[9 * kLanes];   // nominal stress P = dU/dF
  alignas(kAlign) T det_f[kLanes];        // J = det F
  alignas(kAlign) T inv_det[kLanes];      // 1 / J
  alignas(kAlign) T j_m23[kLanes];        // J^-2/3
  alignas(kAlign) T j_m43[kLanes];        // J^-4/3
  alignas(kAlign) T trace_c[kLanes];      // tr C
  alignas(kAlign) T k_numerator[kLanes];  // ((tr C)^2 - tr C^2) / 2
  alignas(kAlign) T energy_density[kLanes];
};
using TetStress = TetStressLanes<1>;

// cof(F) = dJ/dF = J F^-T   (derivative table, paper section 3.2) of a
// row-major F; returns J = det F (paper eq. 3), signed: an inverted element
// is reported, never hidden. Stage 1 of the linear tet and of each
// quadrature point of the quadratic one (quadratic_tet.cc).
template <class T>
inline __attribute__((always_inline)) T cofactor_of_gradient(const T* fl, T* cl) {
  cl[0] = fl[4] * fl[8] - fl[5] * fl[7];
  cl[1] = fl[5] * fl[6] - fl[3] * fl[8];
  cl[2] = fl[3] * fl[7] - fl[4] * fl[6];
  cl[3] = fl[2] * fl[7] - fl[1] * fl[8];
  cl[4] = fl[0] * fl[8] - fl[2] * fl[6];
  cl[5] = fl[1] * fl[6] - fl[0] * fl[7];
  cl[6] = fl[1] * fl[5] - fl[2] * fl[4];
  cl[7] = fl[2] * fl[3] - fl[0] * fl[5];
  cl[8] = fl[0] * fl[4] - fl[1] * fl[3];
  return fl[0] * cl[0] + fl[1] * cl[1] + fl[2] * cl[2];
}

// Stage 1: F = D B and its cofactor; returns J = det F (paper eq. 2-3, 11-12).
// b, f and cof are read with stride S (S = kLanes of a lane block, 1 for one
// tet), the positions with stride SY (default S): b[S k] = B_k,
// y0[SY i] = y_i^1, f[S k] = F_k.
template <int S = 1, int SY = S, class T>
inline __attribute__((always_inline)) T deformation_gradient(const T* b, const T* y0, const T* y1,
                                                             const T* y2, const T* y3, T* f, T* cof) {
  // D_ik = y_i^k - y_i^4   (paper eq. 11, positions instead of displacements since J B = 1)
  T d[9];
  for (int i = 0; i < 3; ++i) {
    d[3 * i + 0] = y0[SY * i] - y3[SY * i];
    d[3 * i + 1] = y1[SY * i] - y3[SY * i];
    d[3 * i + 2] = y2[SY * i] - y3[SY * i];
  }
  T fl[9];
  // F_il = D_ik B_kl   (paper eq. 2 and 11-12)
  for (int i = 0; i < 3; ++i) {
    for (int l = 0; l < 3; ++l) {
      fl[3 * i + l] = d[3 * i + 0] * b[S * l] + d[3 * i + 1] * b[S * (3 + l)] + d[3 * i + 2] * b[S * (6 + l)];
    }
  }
  T cl[9];
  const T det = cofactor_of_gradient(fl, cl);
  for (int k = 0; k < 9; ++k) {
    f[S * k] = fl[k];
    cof[S * k] = cl[k];
  }
  return det;
}

// Stage 3: invariants, energy density and nominal stress of lane `lane` of s
// from s.f, s.cof, s.det_f (> 0) and J^-1/3 (stage 2: inverse_cube_root).
// `pressure` adds pressure cof(F) to the stress and nothing to the energy
// density (the nodal-averaged volumetric energy is summed per vertex,
// elastic_forces.cc). s.stress receives stress_scale P: the force loop passes
// -V0 (forces_from_scaled_stress), which costs three products here instead
// of nine there. kTangentData false (the force loop) skips storing what only
// stress_derivative reads (c, fc and the scalars other than det_f and
// energy_density) and computing F C, which the stress does not need.
template <bool kMooneyRivlin, int S, bool kTangentData = true, class T = double>
inline __attribute__((always_inline)) void stress_from_gradient(T mu1, T mu2, T kappa, T j_m13,
                                                                TetStressLanes<S, T>& s, int lane,
                                                                T pressure = T(0), T stress_scale = T(1)) {
  const T* f = s.f + lane;
  const T* cof = s.cof + lane;
  const T det_f = s.det_f[lane];
  // J^-2/3 and 1/J as products of J^-1/3: no pow(), no division
  const T j_m23 = j_m13 * j_m13;
  const T inv_det = j_m23 * j_m13;
  if constexpr (kTangentData) {
    s.inv_det[lane] = inv_det;
    s.j_m23[lane] = j_m23;
  }
  // C = F^T F (symmetric: six products; Mooney-Rivlin only)
  T c[9];
  T trace_c;
  if constexpr (kMooneyRivlin) {
    c[0] = f[0] * f[0] + f[S * 3] * f[S * 3] + f[S * 6] * f[S * 6];
    c[4] = f[S * 1] * f[S * 1] + f[S * 4] * f[S * 4] + f[S * 7] * f[S * 7];
    c[8] = f[S * 2] * f[S * 2] + f[S * 5] * f[S * 5] + f[S * 8] * f[S * 8];
    c[1] = c[3] = f[0] * f[S * 1] + f[S * 3] * f[S * 4] + f[S * 6] * f[S * 7];
    c[2] = c[6] = f[0] * f[S * 2] + f[S * 3] * f[S * 5] + f[S * 6] * f[S * 8];
    c[5] = c[7] = f[S * 1] * f[S * 2] + f[S * 4] * f[S * 5] + f[S * 7] * f[S * 8];
    // T_C = tr C   (paper eq. 3-4), from the diagonal of C
    trace_c = c[0] + c[4] + c[8];
  } else {
    // T_C = tr C = F_il F_il   (paper eq. 3-4)
    trace_c = T(0);
    for (int k = 0; k < 9; ++k) trace_c += f[S * k] * f[S * k];
  }
  if constexpr (kTangentData) s.trace_c[lane] = trace_c;
  const T jm1 = det_f - T(1);
  // I = T_C J^-2/3   (paper eq. 3)
  const T inv_i = trace_c * j_m23;
  // U = mu1/2 (I - 3) + mu2/2 (K - 3) + kappa/2 (J - 1)^2   (paper eq. 5)
  // (twice U here: the factor 1/2 is applied once at the end)
  T energy = mu1 * (inv_i - T(3)) + kappa * jm1 * jm1;
  // dU/dF = c_F F + c_FC F C + c_cof cof(F), from the derivative table (paper section 3.2):
  // c_F = mu1 J^-2/3 + mu2 T_C J^-4/3, c_FC = -mu2 J^-4/3,
  // c_cof = -mu1/3 T_C J^-5/3 - 2/3 mu2 K' J^-7/3 + kappa (J - 1), K' = (T_C^2 - T_C2) / 2
  T coef_f = mu1 * j_m23;
  T coef_cof = -T(1.0 / 3.0) * mu1 * inv_i * inv_det + kappa * jm1 + pressure;
  T* stress = s.stress + lane;
  if constexpr (kMooneyRivlin) {
    const T j_m43 = j_m23 * j_m23;
    if constexpr (kTangentData) {
      s.j_m43[lane] = j_m43;
      for (int k = 0; k < 9; ++k) s.c[S * k + lane] = c[k];
    }
    // K' = (T_C^2 - T_C2) / 2 with T_C2 = tr C^2 (paper eq. 3-4) is the second
    // invariant of C, the sum of its principal 2x2 minors (six products).
    const T k_numerator =
        (c[0] * c[4] - c[1] * c[1]) + (c[0] * c[8] - c[2] * c[2]) + (c[4] * c[8] - c[5] * c[5]);
    if constexpr (kTangentData) s.k_numerator[lane] = k_numerator;
    // K = K' J^-4/3   (paper eq. 3)
    const T inv_k = k_numerator * j_m43;
    energy += mu2 * (inv_k - T(3));
    coef_f += mu2 * trace_c * j_m43;
    coef_cof -= T(2.0 / 3.0) * mu2 * inv_k * inv_det;
    const T coef_fc = -mu2 * j_m43;
    if constexpr (kTangentData) {
      // (F C)_il = F_im C_ml
      T* fc = s.fc + lane;
      for (int i = 0; i < 3; ++i) {
        for (int l = 0; l < 3; ++l) {
          fc[S * (3 * i + l)] =
              f[S * 3 * i] * c[l] + f[S * (3 * i + 1)] * c[3 + l] + f[S * (3 * i + 2)] * c[6 + l];
        }
      }
    }
    // c_F F + c_FC F C = F M with the symmetric M = c_F 1 + c_FC C: 9 products
    // and 3 sums for M, then 45 for F M, instead of 45 for F C and 45 for the sum.
    const T scaled_f = stress_scale * coef_f;
    const T scaled_fc = stress_scale * coef_fc;
    const T scaled_cof = stress_scale * coef_cof;
    T m[9];
    m[0] = scaled_f + scaled_fc * c[0];
    m[4] = scaled_f + scaled_fc * c[4];
    m[8] = scaled_f + scaled_fc * c[8];
    m[1] = m[3] = scaled_fc * c[1];
    m[2] = m[6] = scaled_fc * c[2];
    m[5] = m[7] = scaled_fc * c[5];
    for (int i = 0; i < 3; ++i) {
      for (int l = 0; l < 3; ++l) {
        stress[S * (3 * i + l)] =
            (f[S * 3 * i] * m[l] + f[S * (3 * i + 1)] * m[3 + l] + f[S * (3 * i + 2)] * m[6 + l]) +
            scaled_cof * cof[S * (3 * i + l)];
      }
    }
  } else {
    const T scaled_f = stress_scale * coef_f;
    const T scaled_cof = stress_scale * coef_cof;
    for (int k = 0; k < 9; ++k) stress[S * k] = scaled_f * f[S * k] + scaled_cof * cof[S * k];
  }
  s.energy_density[lane] = T(0.5) * energy;
}

// All stages for one tet. Returns false for J <= 0 (inverted or flat element):
// the caller reports it and must not use the stress. NaN passes through (the
// test is J <= 0, not !(J > 0)), so a NaN position gives a NaN energy rather
// than a hidden or misnamed failure.
// Stages 2-3 from s.f, s.cof and s.det_f (stage 1 done by the caller).
template <bool kMooneyRivlin>
inline bool stress_at_gradient(const TetParams& p, TetStress& s) {
  if (s.det_f[0] <= 0.0) return false;
  stress_from_gradient<kMooneyRivlin>(p.mu1_pa, p.mu2_pa, p.kappa_pa, inverse_cube_root(s.det_f[0]), s, 0,
                                      p.pressure_pa);
  return true;
}

template <bool kMooneyRivlin>
inline bool tet_stress(const TetParams& p, const double* y0, const double* y1, const double* y2,
                       const double* y3, TetStress& s) {
  s.det_f[0] = deformation_gradient(p.b_matrix, y0, y1, y2, y3, s.f, s.cof);
  return stress_at_gradient<kMooneyRivlin>(p, s);
}

// f_i^a = -V0 dU/dF_kl dF_kl/du_i^a = -V0 P_il B_al for a = 1..3, and
// f^4 = -(f^1 + f^2 + f^3) since dF_kl/du_i^4 = -delta_ki sum_m B_ml   (paper eq. 9-10, section 3.2)
// Writes forces[S (3 a + i)] for the local vertices a = 0..3; b and stress
// are read with stride S as in deformation_gradient.
template <int S = 1>
inline __attribute__((always_inline)) void forces_from_stress(const double* b, double ref_volume_m3,
                                                              const double* stress, double* forces) {
  const double scale = -ref_volume_m3;
  for (int i = 0; i < 3; ++i) {
    const double p0 = scale * stress[S * 3 * i];
    const double p1 = scale * stress[S * (3 * i + 1)];
    const double p2 = scale * stress[S * (3 * i + 2)];
    const double fa0 = p0 * b[0] + p1 * b[S * 1] + p2 * b[S * 2];
    const double fa1 = p0 * b[S * 3] + p1 * b[S * 4] + p2 * b[S * 5];
    const double fa2 = p0 * b[S * 6] + p1 * b[S * 7] + p2 * b[S * 8];
    forces[S * i] = fa0;
    forces[S * (3 + i)] = fa1;
    forces[S * (6 + i)] = fa2;
    forces[S * (9 + i)] = -(fa0 + fa1 + fa2);
  }
}

// As forces_from_stress, from a stress already scaled by -V0
// (stress_from_gradient with stress_scale = -V0): f_i^a = (-V0 P)_il B_al.
template <int S = 1, class T>
inline __attribute__((always_inline)) void forces_from_scaled_stress(const T* b, const T* scaled_stress,
                                                                     T* forces) {
  for (int i = 0; i < 3; ++i) {
    const T p0 = scaled_stress[S * 3 * i];
    const T p1 = scaled_stress[S * (3 * i + 1)];
    const T p2 = scaled_stress[S * (3 * i + 2)];
    const T fa0 = p0 * b[0] + p1 * b[S * 1] + p2 * b[S * 2];
    const T fa1 = p0 * b[S * 3] + p1 * b[S * 4] + p2 * b[S * 5];
    const T fa2 = p0 * b[S * 6] + p1 * b[S * 7] + p2 * b[S * 8];
    forces[S * i] = fa0;
    forces[S * (3 + i)] = fa1;
    forces[S * (6 + i)] = fa2;
    forces[S * (9 + i)] = -(fa0 + fa1 + fa2);
  }
}

// d^2U/dF_il dF_jm as a symmetric 9x9 matrix, row 3 i + l, column 3 j + m.
// Differentiating dU/dF = c_F F + c_FC F C + c_cof cof(F) once more (scalars
// through dT_C = 2 F:dF, dJ = cof:dF, dK' = (2 T_C F - 2 F C):dF):
//   c_F 1 + c_FC d(FC)/dF + c_cof dcof/dF + 2 mu2 J^-4/3 F (x) F
//   + alpha (F (x) cof + cof (x) F) + gamma (FC (x) cof + cof (x) FC) + beta cof (x) cof
// with alpha = -2/3 mu1 J^-5/3 - 4/3 mu2 T_C J^-7/3, gamma = 4/3 mu2 J^-7/3,
// beta = 5/9 mu1 T_C J^-8/3 + 14/9 mu2 K' J^-10/3 + kappa,
// d(FC)_il/dF_jm = delta_ij C_ml + F_im F_jl + (F F^T)_ij delta_lm,
// dcof_il/dF_jm = eps_ijq eps_lms F_qs.
template <bool kMooneyRivlin>
inline void stress_derivative(const TetParams& p, const TetStress& s, double* d2u) {
  const double mu1 = p.mu1_pa;
  const double mu2 = kMooneyRivlin ? p.mu2_pa : 0.0;
  const double* f = s.f;
  const double* cof = s.cof;
  const double inv_det = s.inv_det[0];
  const double j_m23 = s.j_m23[0];
  const double jm1 = s.det_f[0] - 1.0;
  double coef_f = mu1 * j_m23;
  double coef_cof = -(1.0 / 3.0) * mu1 * s.trace_c[0] * j_m23 * inv_det + p.kappa_pa * jm1 + p.pressure_pa;
  double alpha = -(2.0 / 3.0) * mu1 * j_m23 * inv_det;
  double beta = (5.0 / 9.0) * mu1 * s.trace_c[0] * j_m23 * inv_det * inv_det + p.kappa_pa;
  for (int r = 0; r < 9; ++r) {
    for (int q = 0; q < 9; ++q) {
      d2u[9 * r + q] = alpha * (f[r] * cof[q] + cof[r] * f[q]) + beta * cof[r] * cof[q];
    }
  }
  if constexpr (kMooneyRivlin) {
    const double j_m43 = s.j_m43[0];
    const double* fc = s.fc;
    const double* c = s.c;
    coef_f += mu2 * s.trace_c[0] * j_m43;
    coef_cof -= (2.0 / 3.0) * mu2 * s.k_numerator[0] * j_m43 * inv_det;
    const double coef_fc = -mu2 * j_m43;
    const double gamma = (4.0 / 3.0) * mu2 * j_m43 * inv_det;
    const double alpha_k = -(4.0 / 3.0) * mu2 * s.trace_c[0] * j_m43 * inv_det;
    const double beta_k = (14.0 / 9.0) * mu2 * s.k_numerator[0] * j_m43 * inv_det * inv_det;
    const double ff = 2.0 * mu2 * j_m43;
    for (int r = 0; r < 9; ++r) {
      for (int q = 0; q < 9; ++q) {
        d2u[9 * r + q] += ff * f[r] * f[q] + alpha_k * (f[r] * cof[q] + cof[r] * f[q]) +
                          gamma * (fc[r] * cof[q] + cof[r] * fc[q]) + beta_k * cof[r] * cof[q];
      }
    }
    // b = F F^T (left Cauchy-Green)
    double left_cg[9];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        left_cg[3 * i + j] = f[3 * i] * f[3 * j] + f[3 * i + 1] * f[3 * j + 1] + f[3 * i + 2] * f[3 * j + 2];
      }
    }
    // c_FC (delta_ij C_ml + F_im F_jl + b_ij delta_lm)
    for (int i = 0; i < 3; ++i) {
      for (int l = 0; l < 3; ++l) {
        for (int j = 0; j < 3; ++j) {
          for (int m = 0; m < 3; ++m) {
            double term = f[3 * i + m] * f[3 * j + l];
            if (i == j) term += c[3 * m + l];
            if (l == m) term += left_cg[3 * i + j];
            d2u[9 * (3 * i + l) + 3 * j + m] += coef_fc * term;
          }
        }
      }
    }
  }
  // c_F delta_ij delta_lm
  for (int r = 0; r < 9; ++r) d2u[10 * r] += coef_f;
  // c_cof eps_ijq eps_lms F_qs: nonzero only for i != j and l != m, q and s the third indices
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (i == j) continue;
      const int q = 3 - i - j;
      const double eps_ij = (j == (i + 1) % 3) ? 1.0 : -1.0;
      for (int l = 0; l < 3; ++l) {
        for (int m = 0; m < 3; ++m) {
          if (l == m) continue;
          const int sidx = 3 - l - m;
          const double eps_lm = (m == (l + 1) % 3) ? 1.0 : -1.0;
          d2u[9 * (3 * i + l) + 3 * j + m] += coef_cof * eps_ij * eps_lm * f[3 * q + sidx];
        }
      }
    }
  }
}

// The tangent kernel: element energy, 12 forces and the 12x12 block
// K_(a i),(b j) = V0 dF_kl/dy_i^a d^2U/dF_kl dF_pq dF_pq/dy_j^b = V0 B_al (d^2U/dF dF)_(il),(jm) B_bm
// for a, b = 1..3, and rows/columns of vertex 4 as minus the sums over a (b).
// Returns false for J <= 0. Row-major: block[12 (3 a + i) + 3 b + j].
// Forced inline into the scatter of the tangent assembly (tangent_assembler.cc):
// GCC inlined it there while the assembly shared a source file with the force
// loop, and no longer does on its own in the smaller file.
template <bool kMooneyRivlin>
inline __attribute__((always_inline)) bool tet_tangent(const TetParams& p, const double* y0, const double* y1,
                                                       const double* y2, const double* y3, double* forces,
                                                       double* block, double& energy_j) {
  TetStress s;
  if (!tet_stress<kMooneyRivlin>(p, y0, y1, y2, y3, s)) return false;
  forces_from_stress(p.b_matrix, p.ref_volume_m3, s.stress, forces);
  energy_j = p.ref_volume_m3 * s.energy_density[0];
  double d2u[81];
  stress_derivative<kMooneyRivlin>(p, s, d2u);
  const double* b = p.b_matrix;
  // half[(i l), (b j)] = sum_m d2u[(i l), (j m)] B_bm
  double half[81];
  for (int r = 0; r < 9; ++r) {
    for (int bv = 0; bv < 3; ++bv) {
      for (int j = 0; j < 3; ++j) {
        const double* row = d2u + 9 * r + 3 * j;
        half[9 * r + 3 * bv + j] = row[0] * b[3 * bv] + row[1] * b[3 * bv + 1] + row[2] * b[3 * bv + 2];
      }
    }
  }
  const double v0 = p.ref_volume_m3;
  for (int av = 0; av < 3; ++av) {
    for (int i = 0; i < 3; ++i) {
      double* out = block + 12 * (3 * av + i);
      for (int col = 0; col < 9; ++col) {
        out[col] = v0 * (b[3 * av] * half[9 * (3 * i) + col] + b[3 * av + 1] * half[9 * (3 * i + 1) + col] +
                         b[3 * av + 2] * half[9 * (3 * i + 2) + col]);
      }
      // column block of vertex 4: minus the sum over b
      for (int j = 0; j < 3; ++j) out[9 + j] = -(out[j] + out[3 + j] + out[6 + j]);
    }
  }
  // row block of vertex 4: minus the sum over a
  for (int i = 0; i < 3; ++i) {
    double* out = block + 12 * (9 + i);
    for (int col = 0; col < 12; ++col) {
      out[col] = -(block[12 * i + col] + block[12 * (3 + i) + col] + block[12 * (6 + i) + col]);
    }
  }
  return true;
}

}  // namespace cellflow::elastic::kernel
