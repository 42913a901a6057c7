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
// phase p, 256 entries so that any byte indexes inside the table.
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

// Relaxes the pair (I, I + 9) in place.
template <int I, class T>
CELLFLOW_LB_INLINE void relax_pair(T& hi, T& hj, T drho, T rho, T ux, T uy, T uz, T fx, T fy, T fz, T usq15,
                                   T uf3, T omega_plus, T omega_minus, T force_plus, T force_minus) {
  constexpr T w = static_cast<T>(kWeight[I]);
  const T cu = c_dot<I>(ux, uy, uz);
  const T cf = c_dot<I>(fx, fy, fz);
  // f_eq+ - w = w (drho + rho (9/2 (c.u)^2 - 3/2 u.u)),  f_eq- = 3 w rho c.u
  const T eq_sym = w * (drho + rho * (T(4.5) * cu * cu - usq15));
  const T eq_asym = w * rho * T(3) * cu;
  // S+ = w (9 (c.u)(c.F) - 3 u.F),  S- = 3 w c.F   (even and odd parts of Guo's S_i)
  const T src_sym = w * (T(9) * cu * cf - uf3);
  const T src_asym = w * T(3) * cf;
  const T sym = T(0.5) * (hi + hj);
  const T asym = T(0.5) * (hi - hj);
  const T d_sym = force_plus * src_sym - omega_plus * (sym - eq_sym);
  const T d_asym = force_minus * src_asym - omega_minus * (asym - eq_asym);
  hi = hi + d_sym + d_asym;
  hj = hj + d_sym - d_asym;
}

// Collides n consecutive nodes: reads h_i from in[i][x], writes h_i* to
// out[i][x] (in and out may alias node by node), the density to rho_out[x]
// and, if kVelocityOut, the velocity. Body force = uniform + field (if
// kForceField). kPhases: node x relaxes with the coefficients of
// table[phase[x]] instead of k's (which then give only the uniform force).
template <class T, bool kForceField, bool kVelocityOut, bool kPhases = false>
CELLFLOW_LB_INLINE void collide_run(const T* const* in, T* const* out, int n, const T* __restrict fxf,
                                    const T* __restrict fyf, const T* __restrict fzf, T* __restrict uxo,
                                    T* __restrict uyo, T* __restrict uzo, T* __restrict rho_out,
                                    const CollisionCoeffs<T> k,
                                    const std::uint8_t* __restrict phase = nullptr,
                                    const PhaseTable<T>* __restrict table = nullptr) {
  const T *i0 = in[0], *i1 = in[1], *i2 = in[2], *i3 = in[3], *i4 = in[4], *i5 = in[5], *i6 = in[6],
          *i7 = in[7], *i8 = in[8], *i9 = in[9], *i10 = in[10], *i11 = in[11], *i12 = in[12], *i13 = in[13],
          *i14 = in[14], *i15 = in[15], *i16 = in[16], *i17 = in[17], *i18 = in[18];
  T *o0 = out[0], *o1 = out[1], *o2 = out[2], *o3 = out[3], *o4 = out[4], *o5 = out[5], *o6 = out[6],
    *o7 = out[7], *o8 = out[8], *o9 = out[9], *o10 = out[10], *o11 = out[11], *o12 = out[12], *o13 = out[13],
    *o14 = out[14], *o15 = out[15], *o16 = out[16], *o17 = out[17], *o18 = out[18];
#pragma omp simd
  for (int x = 0; x < n; ++x) {
    T h0 = i0[x], h1 = i1[x], h2 = i2[x], h3 = i3[x], h4 = i4[x], h5 = i5[x], h6 = i6[x], h7 = i7[x],
      h8 = i8[x], h9 = i9[x], h10 = i10[x], h11 = i11[x], h12 = i12[x], h13 = i13[x], h14 = i14[x],
      h15 = i15[x], h16 = i16[x], h17 = i17[x], h18 = i18[x];
    // drho = sum_i h_i
    const T drho = ((h0 + h1) + (h2 + h3)) + ((h4 + h5) + (h6 + h7)) + ((h8 + h9) + (h10 + h11)) +
                   ((h12 + h13) + (h14 + h15)) + ((h16 + h17) + h18);
    const T rho = T(1) + drho;
    // j = sum_i h_i c_i (the w_i c_i sum to zero)
    const T jx = (h1 - h10) + (h4 - h13) + (h5 - h14) + (h6 - h15) + (h7 - h16);
    const T jy = (h2 - h11) + (h4 - h13) - (h5 - h14) + (h8 - h17) + (h9 - h18);
    const T jz = (h3 - h12) + (h6 - h15) - (h7 - h16) + (h8 - h17) - (h9 - h18);
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
    const T usq15 = T(1.5) * (ux * ux + uy * uy + uz * uz);
    const T uf3 = T(3) * (ux * fx + uy * fy + uz * fz);
    T op = k.omega_plus, om = k.omega_minus, fp = k.force_plus, fm = k.force_minus;
    if constexpr (kPhases) {
      const int ph = phase[x];
      op = table->omega_plus[ph];
      om = table->omega_minus[ph];
      fp = table->force_plus[ph];
      fm = table->force_minus[ph];
    }
    // rest population: only the symmetric part relaxes; S_0 = -3 w_0 u.F
    constexpr T w0 = static_cast<T>(kWeight[0]);
    h0 = h0 - op * (h0 - w0 * (drho - rho * usq15)) - fp * w0 * uf3;
    relax_pair<1>(h1, h10, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<2>(h2, h11, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<3>(h3, h12, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<4>(h4, h13, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<5>(h5, h14, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<6>(h6, h15, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<7>(h7, h16, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<8>(h8, h17, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
    relax_pair<9>(h9, h18, drho, rho, ux, uy, uz, fx, fy, fz, usq15, uf3, op, om, fp, fm);
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
