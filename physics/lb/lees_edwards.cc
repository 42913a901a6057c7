// Lees-Edwards boundaries in y (lees_edwards.h): the moments of the layers
// next to the plane before the step, and the re-mapping of the populations
// that crossed it after the step, wherever the storage scheme keeps them.
#include "physics/lb/lees_edwards.h"

#include <cmath>
#include <string>

#include "physics/lb/fluid_internal.h"

namespace cellflow::lb {

namespace {

// The largest |U|: the layers next to the plane move at about U / 2, and a
// lattice speed of 0.25 is Mach 0.43, far beyond the low-Mach equilibrium.
constexpr double kMaxImageVelocity = 0.5;

// f_eq_q(rho, u + du e_x) - f_eq_q(rho, u) with
// f_eq_q = w_q rho (1 + 3 c.u + 9/2 (c.u)^2 - 3/2 u.u)   (2nd-order equilibrium)
double equilibrium_shift(int q, double rho, double ux, double uy, double uz, double du) {
  const double cu = kCx[q] * ux + kCy[q] * uy + kCz[q] * uz;
  const double cu_new = cu + kCx[q] * du;
  const double ux_new = ux + du;
  return kWeight[q] * rho *
         (3.0 * kCx[q] * du + 4.5 * (cu_new * cu_new - cu * cu) - 1.5 * (ux_new * ux_new - ux * ux));
}

}  // namespace

LeesEdwards::LeesEdwards(int nx, int nz, double image_velocity)
    : nx_(nx),
      nz_(nz),
      image_velocity_(image_velocity),
      rho_(2 * static_cast<std::size_t>(nx) * nz),
      ux_(rho_.size()),
      uy_(rho_.size()),
      uz_(rho_.size()),
      row_(nx) {}

StatusOr<LeesEdwards> LeesEdwards::make(const Fluid& fluid, double image_velocity) {
  if (fluid.params().walls_y)
    return invalid_argument("lb: Lees-Edwards boundaries need a fluid periodic in y (walls_y = false)");
  if (fluid.ny() < 2)
    return invalid_argument("lb: Lees-Edwards boundaries need ny >= 2 (ny = " + std::to_string(fluid.ny()) +
                            ")");
  if (!(std::abs(image_velocity) <= kMaxImageVelocity))
    return invalid_argument("lb: Lees-Edwards image velocity must be finite with |U| <= 0.5 (lattice units)");
  return LeesEdwards(fluid.nx(), fluid.nz(), image_velocity);
}

double LeesEdwards::offset(std::int64_t time_step) const {
  const double delta = std::fmod(image_velocity_ * static_cast<double>(time_step), static_cast<double>(nx_));
  return delta < 0.0 ? delta + nx_ : delta;
}

// Row by row (not node by node through lb::populations: 5 x faster, the
// moments were a quarter of the step): the pre-collision deviation h_q of
// the nodes of one row is one row of the storage, shifted by c_x in the
// swapped AA layout.
template <class T>
void LeesEdwards::layer_moments(const Fluid& fluid) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  const T* a = FluidAccess::populations<T>(fluid).data();
  bool swapped = false;
  if (p.streaming == Streaming::kTwoArray)
    a += FluidAccess::current(fluid) * kQ * stride;
  else
    swapped = FluidAccess::aa_swapped(fluid);
  const VectorField<const T> force = fluid.force_field<T>();
  const int nx = nx_;
  const int layers[2] = {0, p.ny - 1};
  for (int l = 0; l < 2; ++l) {
    const int j = layers[l];
    for (int k = 0; k < nz_; ++k) {
      const std::size_t m0 = static_cast<std::size_t>(nx) * (static_cast<std::size_t>(l) * nz_ + k);
      double* rho = rho_.data() + m0;
      double* jx = ux_.data() + m0;
      double* jy = uy_.data() + m0;
      double* jz = uz_.data() + m0;
      for (int i = 0; i < nx; ++i) rho[i] = jx[i] = jy[i] = jz[i] = 0.0;
      for (int q = 0; q < kQ; ++q) {
        // Swapped AA layout: slot qbar at x - c_q holds f*_q of the last collision.
        const T* row =
            swapped ? a + opposite(q) * stride + fluid.node(0, wrap(j - kCy[q], p.ny), wrap(k - kCz[q], nz_))
                    : a + q * stride + fluid.node(0, j, k);
        // h[i] = row[wrap(i + shift)], |shift| <= 1: the wrap only at the ends.
        const int shift = swapped ? -kCx[q] : 0;
        double* h = row_.data();
        for (int i = 1; i < nx - 1; ++i) h[i] = static_cast<double>(row[i + shift]);
        h[0] = static_cast<double>(row[wrap(shift, nx)]);
        h[nx - 1] = static_cast<double>(row[wrap(nx - 1 + shift, nx)]);
        const double cx = kCx[q], cy = kCy[q], cz = kCz[q];
        for (int i = 0; i < nx; ++i) {
          const double v = h[i];
          rho[i] += v;
          jx[i] += cx * v;
          jy[i] += cy * v;
          jz[i] += cz * v;
        }
      }
      const std::size_t at = fluid.node(0, j, k);
      for (int i = 0; i < nx; ++i) {
        double fx = p.uniform_force[0], fy = p.uniform_force[1], fz = p.uniform_force[2];
        if (force.x != nullptr) {
          fx += force.x[at + i];
          fy += force.y[at + i];
          fz += force.z[at + i];
        }
        // u = (sum_i f_i c_i + F/2) / rho   (Guo 2002, eq. 7): the velocity of the collision
        const double r = 1.0 + rho[i];  // deviations: rho = 1 + sum_q h_q
        rho[i] = r;
        jx[i] = (jx[i] + 0.5 * fx) / r;
        jy[i] = (jy[i] + 0.5 * fy) / r;
        jz[i] = (jz[i] + 0.5 * fz) / r;
      }
    }
  }
}

// After the step the populations that crossed the plane sit in one row per
// direction and z: with the AA pattern after an even step (not streamed yet)
// in slot qbar of the source layer, the slot the next odd step streams from;
// after an odd step or a two-array step in slot q of the destination layer.
// Either way the row is a plain x-translate of the source row, so shifting
// the row shifts the arrival point.
template <class T>
void LeesEdwards::remap_crossing(Fluid& fluid) {
  const FluidParams& p = fluid.params();
  const int nx = nx_, ny = p.ny, nz = nz_;
  const std::size_t stride = FluidAccess::stride(fluid);
  T* a = FluidAccess::populations<T>(fluid).data();
  bool streamed = true;
  if (p.streaming == Streaming::kTwoArray)
    a += FluidAccess::current(fluid) * kQ * stride;
  else
    streamed = !FluidAccess::aa_swapped(fluid);
  // The populations arrive at step t + 1 = fluid.time_step().
  const double delta = offset(fluid.time_step());
  for (int down = 0; down < 2; ++down) {
    // down: c_y = +1 crosses y = ny from layer ny - 1 into layer 0, from the
    // image below (at -U, displaced by -Delta in our coordinates):
    // f(x, 0) = f(x - c_x + Delta, ny - 1) shifted by -U. Up: the mirror.
    const int cy = down ? 1 : -1;
    const int src_layer = down ? ny - 1 : 0, dst_layer = down ? 0 : ny - 1;
    const int src_moments = down ? 1 : 0;
    const double du = down ? -image_velocity_ : image_velocity_;
    double shift = down ? delta : nx - delta;  // read position x + shift, in [0, nx]
    if (shift >= nx) shift -= nx;
    const int whole = static_cast<int>(std::floor(shift));
    const double frac = shift - whole;
    for (int q = 1; q < kQ; ++q) {
      if (kCy[q] != cy) continue;
      for (int k = 0; k < nz; ++k) {
        T* row = streamed ? a + q * stride + fluid.node(0, dst_layer, k)
                          : a + opposite(q) * stride + fluid.node(0, src_layer, k);
        // The source node of row element i and its moments.
        const int ks = streamed ? wrap(k - kCz[q], nz) : k;
        const std::size_t m0 =
            static_cast<std::size_t>(nx) * (static_cast<std::size_t>(src_moments) * nz + ks);
        for (int i = 0; i < nx; ++i) {
          const int is = streamed ? wrap(i - kCx[q], nx) : i;
          const std::size_t m = m0 + is;
          row_[i] = static_cast<double>(row[i]) + equilibrium_shift(q, rho_[m], ux_[m], uy_[m], uz_[m], du);
        }
        // Linear interpolation at x + shift: each value is split between two
        // neighbours with weights summing to 1, so the row's mass is kept.
        for (int i = 0; i < nx; ++i) {
          int i0 = i + whole;
          if (i0 >= nx) i0 -= nx;
          const int i1 = i0 + 1 == nx ? 0 : i0 + 1;
          row[i] = static_cast<T>((1.0 - frac) * row_[i0] + frac * row_[i1]);
        }
      }
    }
  }
}

void LeesEdwards::collide_stream(Fluid& fluid) {
  if (fluid.params().precision == Precision::kDouble) {
    layer_moments<double>(fluid);
    lb::collide_stream(fluid);
    remap_crossing<double>(fluid);
  } else {
    layer_moments<float>(fluid);
    lb::collide_stream(fluid);
    remap_crossing<float>(fluid);
  }
}

}  // namespace cellflow::lb
