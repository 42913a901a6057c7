// The per-node TRT collision with Guo forcing, vectorised across a run of
// consecutive x nodes. Internal to cellflow::lb (included by fluid_step.cc and the
// benchmark's kernel check only); the public API is physics/lb/fluid.h.
//
// Populations are deviations h_i = f_i - w_i. For one node:
//   rho = 1 + sum_i h_i,   rho u = sum_i h_i c_i + F / 2              (Guo 2002, eq. 7)
//   f_eq_i - w_i = w_i [drho + rho (3 c.u + 9/2 (c.u)^2 - 3/2 u.u)]   (2nd-order equilibrium)
//   S_i = w_i [3 (c_i - u) + 9 (c_i.u) c_i] . F                       (Guo 2002, eq. 20)
// TRT (Ginzburg 2008) on each pair (i, ibar), with g+- = (g_i +- g_ibar) / 2:
//   f_i* = f_i - w+ (f+ - f_eq+) - w- (f- - f_eq-) + (1 - w+/2) S+ + (1 - w-/2) S-
#pragma once

#include <cstdint>

#include "physics/lb/d3q19.h"

// Everything the row loops call is forced inline, so that it is compiled for
// the instruction set of the row loop it ends up in (fluid_step.cc builds one row
// loop per SIMD level with __attribute__((target)); no out-of-line copy of a
// kernel function can be shared between levels).
#define CELLFLOW_LB_INLINE inline __attribute__((always_inline))

namespace cellflow::lb::detail {

// Relaxation and forcing coefficients of one step, in the compute type T.
template <class T>
struct CollisionCoeffs {
  T omega_plus;   // 1 / tau
  T omega_minus;  // 1 / tau_minus; = omega_plus for BGK
  T force_plus;   // 1 - omega_plus / 2
  T force_minus;  // 1 - omega_minus / 2
  T gx, gy, gz;   // uniform body-force density
};

// Per-phase coefficients (viscosity contrast): entry p for the nodes of
// phase p, 256 entries so that any byte indexes inside the table. The row
// kernels collide each run of one phase with its entry (stream_kernel.h).
template <class T>
struct PhaseTable {
  alignas(64) T omega_plus[256];
  alignas(64) T omega_minus[256];
  alignas(64) T force_plus[256];
  alignas(64) T force_minus[256];
};

// c_i . a with the zero components of c_i left out (0 * a is not folded away
// in IEEE arithmetic).
template <int I, class T>
CELLFLOW_LB_INLINE T c_dot(T ax, T ay, T az) {
  constexpr int cx = kCx[I], cy = kCy[I], cz = kCz[I];
  constexpr auto term = [](int c, T a) { return c > 0 ? a : -a; };
  if constexpr (cx != 0 && cy != 0)
    return term(cx, ax) + term(cy, ay);
  else if constexpr (cx != 0 && cz != 0)
    return term(cx, ax) + term(cz, az);
  else if constexpr (cy != 0 && cz != 0)
    return term(cy, ay) + term(cz, az);
  else if constexpr (cx != 0)
    return term(cx, ax);
  else if constexpr (cy != 0)
    return term(cy, ay);
  else
    return term(cz, az);
}

// Relaxes the pair (I, I + 9) in place; sum = h_i + h_ibar, diff = h_i - h_ibar.
// The TRT update of the header, regrouped so that every term that does not
// depend on the direction is formed once per node (collide_run):
//   D+ = (1 - w+/2) S+ - w+ (f+ - f_eq+) = w_i (A + (c.u)(c.V)) - w+/2 sum
//   D- = (1 - w-/2) S- - w- (f- - f_eq-) = 3 w_i (c.W) - w-/2 diff
// with A = w+ (drho - 3/2 rho u.u) - 3 (1 - w+/2) u.F,
//      V = 9/2 w+ rho u + 9 (1 - w+/2) F,  W = w- rho u + (1 - w-/2) F,
// and h_i* = h_i + D+ + D-, h_ibar* = h_ibar + D+ - D-.
// 12 to 15 operations per pair instead of 27 to 29 (the kernel is bound by
// its arithmetic, not by memory, on one core; bench_lb).
template <int I, class T>
CELLFLOW_LB_INLINE void relax_pair(T& hi, T& hj, T sum, T diff, T ux, T uy, T uz, T vx, T vy, T vz, T wx,
                                   T wy, T wz, T a, T half_omega_plus, T half_omega_minus) {
  constexpr T w = static_cast<T>(kWeight[I]);
  constexpr T w3 = static_cast<T>(3.0 * kWeight[I]);
  const T cu = c_dot<I>(ux, uy, uz);
  const T cv = c_dot<I>(vx, vy, vz);
  const T cw = c_dot<I>(wx, wy, wz);
  const T d_sym = w * (a + cu * cv) - half_omega_plus * sum;
  const T d_asym = w3 * cw - half_omega_minus * diff;
  hi = (hi + d_sym) + d_asym;
  hj = (hj + d_sym) - d_asym;
}

// Collides n consecutive nodes: reads h_i from in[i][x], writes h_i* to
// out[i][x] (in and out may alias node by node), the density to rho_out[x]
// and, if kVelocityOut, the velocity. Body force = uniform + field (if
// kForceField).
template <class T, bool kForceField, bool kVelocityOut>
CELLFLOW_LB_INLINE void collide_run(const T* const* in, T* const* out, int n, const T* __restrict fxf,
                                    const T* __restrict fyf, const T* __restrict fzf, T* __restrict uxo,
                                    T* __restrict uyo, T* __restrict uzo, T* __restrict rho_out,
                                    const CollisionCoeffs<T> k) {
  const T *i0 = in[0], *i1 = in[1], *i2 = in[2], *i3 = in[3], *i4 = in[4], *i5 = in[5], *i6 = in[6],
          *i7 = in[7], *i8 = in[8], *i9 = in[9], *i10 = in[10], *i11 = in[11], *i12 = in[12], *i13 = in[13],
          *i14 = in[14], *i15 = in[15], *i16 = in[16], *i17 = in[17], *i18 = in[18];
  T *o0 = out[0], *o1 = out[1], *o2 = out[2], *o3 = out[3], *o4 = out[4], *o5 = out[5], *o6 = out[6],
    *o7 = out[7], *o8 = out[8], *o9 = out[9], *o10 = out[10], *o11 = out[11], *o12 = out[12], *o13 = out[13],
    *o14 = out[14], *o15 = out[15], *o16 = out[16], *o17 = out[17], *o18 = out[18];
  const T op = k.omega_plus, om = k.omega_minus, fp = k.force_plus, fm = k.force_minus;
  const T half_op = T(0.5) * op, half_om = T(0.5) * om;
  const T op45 = T(4.5) * op, fp9 = T(9) * fp, fp3 = T(3) * fp;
  const T keep0 = T(1) - op;
  constexpr T w0 = static_cast<T>(kWeight[0]);
#pragma omp simd
  for (int x = 0; x < n; ++x) {
    T h0 = i0[x], h1 = i1[x], h2 = i2[x], h3 = i3[x], h4 = i4[x], h5 = i5[x], h6 = i6[x], h7 = i7[x],
      h8 = i8[x], h9 = i9[x], h10 = i10[x], h11 = i11[x], h12 = i12[x], h13 = i13[x], h14 = i14[x],
      h15 = i15[x], h16 = i16[x], h17 = i17[x], h18 = i18[x];
    // Pair sums and differences: the density and momentum below, and the
    // symmetric and antisymmetric parts of the TRT pairs.
    const T s1 = h1 + h10, s2 = h2 + h11, s3 = h3 + h12, s4 = h4 + h13, s5 = h5 + h14, s6 = h6 + h15,
            s7 = h7 + h16, s8 = h8 + h17, s9 = h9 + h18;
    const T d1 = h1 - h10, d2 = h2 - h11, d3 = h3 - h12, d4 = h4 - h13, d5 = h5 - h14, d6 = h6 - h15,
            d7 = h7 - h16, d8 = h8 - h17, d9 = h9 - h18;
    // drho = sum_i h_i
    const T drho = ((h0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7)) + (s8 + s9);
    const T rho = T(1) + drho;
    // j = sum_i h_i c_i (the w_i c_i sum to zero)
    const T jx = ((d1 + d4) + (d5 + d6)) + d7;
    const T jy = ((d2 + d4) - (d5 - d8)) + d9;
    const T jz = ((d3 + d6) - (d7 - d8)) - d9;
    T fx = k.gx, fy = k.gy, fz = k.gz;
    if constexpr (kForceField) {
      fx += fxf[x];
      fy += fyf[x];
      fz += fzf[x];
    }
    // u = (j + F/2) / rho   (Guo 2002, eq. 7)
    const T inv_rho = T(1) / rho;
    const T ux = (jx + T(0.5) * fx) * inv_rho;
    const T uy = (jy + T(0.5) * fy) * inv_rho;
    const T uz = (jz + T(0.5) * fz) * inv_rho;
    if constexpr (kVelocityOut) {
      uxo[x] = ux;
      uyo[x] = uy;
      uzo[x] = uz;
    }
    rho_out[x] = rho;
    // The direction-independent terms of relax_pair.
    const T usq15 = T(1.5) * ((ux * ux + uy * uy) + uz * uz);
    const T uf = (ux * fx + uy * fy) + uz * fz;
    const T a = op * (drho - rho * usq15) - fp3 * uf;
    const T r45 = op45 * rho, rm = om * rho;
    const T vx = r45 * ux + fp9 * fx, vy = r45 * uy + fp9 * fy, vz = r45 * uz + fp9 * fz;
    const T wx = rm * ux + fm * fx, wy = rm * uy + fm * fy, wz = rm * uz + fm * fz;
    // rest population: only the symmetric part relaxes; S_0 = -3 w_0 u.F, so
    // h_0* = h_0 - w+ (h_0 - w_0 (drho - 3/2 rho u.u)) - 3 (1 - w+/2) w_0 u.F
    h0 = keep0 * h0 + w0 * a;
    relax_pair<1>(h1, h10, s1, d1, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<2>(h2, h11, s2, d2, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<3>(h3, h12, s3, d3, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<4>(h4, h13, s4, d4, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<5>(h5, h14, s5, d5, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<6>(h6, h15, s6, d6, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<7>(h7, h16, s7, d7, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<8>(h8, h17, s8, d8, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    relax_pair<9>(h9, h18, s9, d9, ux, uy, uz, vx, vy, vz, wx, wy, wz, a, half_op, half_om);
    o0[x] = h0;
    o1[x] = h1;
    o2[x] = h2;
    o3[x] = h3;
    o4[x] = h4;
    o5[x] = h5;
    o6[x] = h6;
    o7[x] = h7;
    o8[x] = h8;
    o9[x] = h9;
    o10[x] = h10;
    o11[x] = h11;
    o12[x] = h12;
    o13[x] = h13;
    o14[x] = h14;
    o15[x] = h15;
    o16[x] = h16;
    o17[x] = h17;
    o18[x] = h18;
  }
}

}  // namespace cellflow::lb::detail
