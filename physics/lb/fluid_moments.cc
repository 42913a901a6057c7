// Macroscopic state of the fluid: the equilibrium initialisation
// (set_equilibrium), the density and velocity moments with the Guo
// correction (compute_moments, update_velocity_field), the total mass and
// the populations of one node, all read through node_deviations, which
// undoes the swapped AA layout.
#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include "physics/lb/fluid.h"
#include "physics/lb/fluid_internal.h"

namespace cellflow::lb {

namespace {

// Pre-collision deviations h_q = f_q - w_q of one node at the current time.
template <class T>
void node_deviations(const Fluid& fluid, int i, int j, int k, double* h) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  const T* a = FluidAccess::populations<T>(fluid).data();
  const std::size_t at = fluid.node(i, j, k);
  if (p.streaming == Streaming::kTwoArray) {
    a += FluidAccess::current(fluid) * kQ * stride;
    for (int q = 0; q < kQ; ++q) h[q] = a[q * stride + at];
    return;
  }
  if (!FluidAccess::aa_swapped(fluid)) {
    for (int q = 0; q < kQ; ++q) h[q] = a[q * stride + at];
    return;
  }
  // Swapped AA layout: slot qbar at x holds f*_q(x) of the last collision;
  // across a wall the kernel bounces back with the density it saved.
  const WallTerms<T> wall = wall_terms<T>(p);
  for (int q = 0; q < kQ; ++q) {
    const int ys = j - kCy[q];
    if (p.walls_y && (ys < 0 || ys >= p.ny)) {
      const T* term = ys < 0 ? wall.lower : wall.upper;
      const T rho_prev =
          FluidAccess::wall_density<T>(fluid)[static_cast<std::size_t>(p.nx) * ((j == 0 ? 0 : p.nz) + k) + i];
      h[q] = a[q * stride + at] + term[q] * rho_prev;
    } else {
      const std::size_t src = fluid.node(wrap(i - kCx[q], p.nx), wrap(ys, p.ny), wrap(k - kCz[q], p.nz));
      h[q] = a[opposite(q) * stride + src];
    }
  }
}

template <class T>
void set_equilibrium_typed(Fluid& fluid, std::span<const double> density, std::span<const double> ux,
                           std::span<const double> uy, std::span<const double> uz) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  T* a = FluidAccess::populations<T>(fluid).data();
  if (p.streaming == Streaming::kTwoArray) a += FluidAccess::current(fluid) * kQ * stride;
  const std::ptrdiff_t nodes = static_cast<std::ptrdiff_t>(fluid.num_nodes());
#pragma omp parallel for schedule(static) num_threads(thread_count(p))
  for (std::ptrdiff_t n = 0; n < nodes; ++n) {
    const double rho = density.empty() ? 1.0 : density[n];
    const double vx = ux[n], vy = uy[n], vz = uz[n];
    const double usq = vx * vx + vy * vy + vz * vz;
    for (int q = 0; q < kQ; ++q) {
      const double cu = kCx[q] * vx + kCy[q] * vy + kCz[q] * vz;
      // f_eq - w = w ((rho - 1) + rho (3 c.u + 9/2 (c.u)^2 - 3/2 u.u))
      a[q * stride + n] =
          static_cast<T>(kWeight[q] * ((rho - 1.0) + rho * (3.0 * cu + 4.5 * cu * cu - 1.5 * usq)));
    }
  }
  FluidAccess::aa_swapped(fluid) = false;
}

template <class T>
void compute_moments_typed(const Fluid& fluid, std::span<double> density, std::span<double> ux,
                           std::span<double> uy, std::span<double> uz) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  const T* force = p.force_field ? FluidAccess::force<T>(fluid).data() : nullptr;
  const int nx = p.nx, ny = p.ny, nz = p.nz;
#pragma omp parallel for collapse(2) schedule(static) num_threads(thread_count(p))
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        double h[kQ];
        node_deviations<T>(fluid, i, j, k, h);
        const std::size_t at = fluid.node(i, j, k);
        double rho = 1.0, jx = 0.0, jy = 0.0, jz = 0.0;
        for (int q = 0; q < kQ; ++q) {
          rho += h[q];
          jx += kCx[q] * h[q];
          jy += kCy[q] * h[q];
          jz += kCz[q] * h[q];
        }
        double fx = p.uniform_force[0], fy = p.uniform_force[1], fz = p.uniform_force[2];
        if (force) {
          fx += force[at];
          fy += force[stride + at];
          fz += force[2 * stride + at];
        }
        // u = (sum_i f_i c_i + F/2) / rho   (Guo 2002, eq. 7)
        if (!density.empty()) density[at] = rho;
        if (!ux.empty()) ux[at] = (jx + 0.5 * fx) / rho;
        if (!uy.empty()) uy[at] = (jy + 0.5 * fy) / rho;
        if (!uz.empty()) uz[at] = (jz + 0.5 * fz) / rho;
      }
}

}  // namespace

void set_equilibrium(Fluid& fluid, std::span<const double> density, std::span<const double> ux,
                     std::span<const double> uy, std::span<const double> uz) {
  if (fluid.params().precision == Precision::kDouble)
    set_equilibrium_typed<double>(fluid, density, ux, uy, uz);
  else
    set_equilibrium_typed<float>(fluid, density, ux, uy, uz);
}

void compute_moments(const Fluid& fluid, std::span<double> density, std::span<double> ux,
                     std::span<double> uy, std::span<double> uz) {
  if (fluid.params().precision == Precision::kDouble)
    compute_moments_typed<double>(fluid, density, ux, uy, uz);
  else
    compute_moments_typed<float>(fluid, density, ux, uy, uz);
}

void update_velocity_field(Fluid& fluid) {
  if (!fluid.params().velocity_field) return;
  const std::size_t n = fluid.num_nodes();
  std::vector<double> ux(n), uy(n), uz(n);
  compute_moments(fluid, {}, ux, uy, uz);
  const auto store = [&](auto& arr) {
    const std::size_t stride = FluidAccess::stride(fluid);
    for (std::size_t i = 0; i < n; ++i) {
      arr[i] = ux[i];
      arr[stride + i] = uy[i];
      arr[2 * stride + i] = uz[i];
    }
  };
  if (fluid.params().precision == Precision::kDouble)
    store(FluidAccess::velocity<double>(fluid));
  else
    store(FluidAccess::velocity<float>(fluid));
}

double total_mass(const Fluid& fluid) {
  // N + sum of the density deviations, so the rest mass does not swamp them.
  const FluidParams& p = fluid.params();
  double deviation = 0.0;
#pragma omp parallel for collapse(2) schedule(static) reduction(+ : deviation) num_threads(thread_count(p))
  for (int k = 0; k < p.nz; ++k)
    for (int j = 0; j < p.ny; ++j)
      for (int i = 0; i < p.nx; ++i) {
        double h[kQ];
        if (p.precision == Precision::kDouble)
          node_deviations<double>(fluid, i, j, k, h);
        else
          node_deviations<float>(fluid, i, j, k, h);
        for (int q = 0; q < kQ; ++q) deviation += h[q];
      }
  return static_cast<double>(fluid.num_nodes()) + deviation;
}

std::array<double, kQ> populations(const Fluid& fluid, int i, int j, int k) {
  std::array<double, kQ> f{};
  if (fluid.params().precision == Precision::kDouble)
    node_deviations<double>(fluid, i, j, k, f.data());
  else
    node_deviations<float>(fluid, i, j, k, f.data());
  for (int q = 0; q < kQ; ++q) f[q] += kWeight[q];
  return f;
}

}  // namespace cellflow::lb
