// D3Q19 lattice Boltzmann fluid in lattice units (dx = dt = 1, c_s^2 = 1/3,
// reference density 1). SI quantities never enter here: physics/units converts.
//
// Geometry. Node (i, j, k), 0 <= i < nx, ..., sits at (i + 1/2, j + 1/2, k + 1/2);
// the box is [0, nx) x [0, ny) x [0, nz). x and z are periodic. In y either
// periodic too, or bounded by two flat walls at y = 0 and y = ny (half-way
// bounce-back: exactly half a spacing beyond the first and last node layers)
// that may move tangentially (plane Couette).
//
// Collision. TRT (two relaxation times): the symmetric populations relax with
// tau (viscosity nu = (tau - 1/2) / 3), the antisymmetric ones with tau_minus
// fixed by the magic parameter Lambda = (tau - 1/2)(tau_minus - 1/2). Lambda
// = 3/16 puts bounce-back walls exactly half-way for any tau, so Poiseuille and
// Couette profiles are exact. BGK (tau_minus = tau) is an option. Forcing by
// Guo et al. (2002): the velocity that enters the equilibrium and the one this
// module reports is u = (sum_i f_i c_i + F/2) / rho.
//
// Storage. Populations are stored as deviations f_i - w_i from the rest state
// (so float storage keeps its digits for the small perturbations), structure
// of arrays, one array per direction, x innermost. float or double is chosen at
// run time; the kernels are templates on the storage type. Two streaming
// schemes: the in-place AA pattern (Bailey et al. 2009; one population array,
// no write-allocate traffic; the default: 1.9x the two-array throughput in
// bench/lb) and the two-array push scheme (the reference; both give the same
// fields to the last bit). The collide-stream loops are built for SSE2, AVX2
// and AVX-512 and the best one the CPU has is used.
//
// Phases (viscosity contrast). With FluidParams::phase_taus non-empty a
// per-node phase index (one byte, 0 everywhere at first) is allocated; node
// x relaxes with tau_p, p = phase(x): p = 0 the fluid's own tau, p >= 1
// phase_taus[p - 1], each with its own TRT tau_minus (the same magic
// Lambda) and its own Guo forcing factors (1 - omega/2). The velocity
// u = (sum f c + F/2) / rho and the density do not depend on tau (Guo 2002),
// so the moments need no phase. Without phase_taus the kernels are exactly
// those of a single tau (no phase field read). A phase table lookup (1 byte
// per node read, 4 coefficients gathered from a table of at most 256 entries)
// costs less memory traffic than a per-node relaxation time (8 bytes) and
// needs no per-node division for tau_minus.
//
// Coupling. A force-density field (3 arrays) and a velocity field (3 arrays),
// both in the storage precision, can be allocated. collide_stream adds the
// force field (plus a uniform body force) via Guo forcing and writes the
// velocity field of the same step inside the fused kernel, so an
// immersed-boundary step needs no extra pass over the lattice:
//   zero_force_field(fluid); ibm::spread_forces(...); collide_stream(fluid);
//   ibm::interpolate_velocity(...); move vertices.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "physics/core/status.h"
#include "physics/lb/aligned_array.h"
#include "physics/lb/d3q19.h"

namespace cellflow::lb {

enum class CollisionModel { kTrt, kBgk };
enum class Precision { kDouble, kFloat };
enum class Streaming { kAA, kTwoArray };
// Instruction set of the collide-stream loops. kAuto takes the best this CPU
// has; all levels give bit-identical results (no FMA contraction).
enum class Simd { kAuto, kGeneric, kAvx2, kAvx512 };

// Everything here is in lattice units.
struct FluidParams {
  int nx = 0, ny = 0, nz = 0;  // nodes per direction, >= 1
  double tau = 1.0;            // relaxation time of the viscous modes, > 0.5; nu = (tau - 1/2) / 3
  CollisionModel collision = CollisionModel::kTrt;
  double trt_magic = 3.0 / 16.0;  // Lambda > 0; 3/16: walls exactly half-way, 1/4: most stable
  bool walls_y = true;            // false: periodic in y as well
  // Tangential wall velocities (the y component must be 0): the lower wall at
  // y = 0 and the upper wall at y = ny. Plane Couette: {-u, 0, 0} and {+u, 0, 0}.
  std::array<double, 3> lower_wall_velocity{0.0, 0.0, 0.0};
  std::array<double, 3> upper_wall_velocity{0.0, 0.0, 0.0};
  std::array<double, 3> uniform_force{0.0, 0.0, 0.0};  // body-force density on every node
  bool force_field = false;     // allocate a per-node force-density field (e.g. IBM spreading target)
  bool velocity_field = false;  // allocate a per-node velocity field written by collide_stream
  // Relaxation times of the phases 1..n (n <= kMaxPhases), each in (0.5, inf);
  // empty: no phase field (every node relaxes with tau).
  std::vector<double> phase_taus;
  Precision precision = Precision::kDouble;
  Streaming streaming = Streaming::kAA;
  int threads = 0;  // OpenMP threads for the lattice loops; 0 = OpenMP default
  Simd simd = Simd::kAuto;
};

inline constexpr int kMaxPhases = 255;

// Relaxation times below this are refused by the flow scenes (not by this
// module, whose limit is tau > 1/2): the TRT lattice at a few percent Mach
// loses stability as tau -> 1/2 (tests/lb/phase_test.cc, shear wave at
// tau = 0.505 stable, decay rate within 1 %).
inline constexpr double kMinStableTau = 0.505;

// tau of a fluid with viscosity lambda times that of a fluid of relaxation
// time tau:  eta = rho c_s^2 (tau - 1/2) dt, so tau_in - 1/2 = lambda (tau - 1/2).
inline double tau_for_viscosity_ratio(double tau, double lambda) {
  return 0.5 + lambda * (tau - 0.5);
}

// The best SIMD level of this CPU, whether a level can run here, its name.
Simd best_simd();
bool simd_supported(Simd simd);
const char* simd_name(Simd simd);

// Checks every field; messages name the field and its allowed range.
Status validate(const FluidParams& params);

// Bytes the lattice of `params` allocates (populations and coupling fields),
// for the memory-limit check before anything is allocated.
std::size_t memory_bytes(const FluidParams& params);

// Three component arrays of one vector field over the lattice, x innermost:
// node (i, j, k) is element i + nx (j + ny k).
template <class T>
struct VectorField {
  T* x = nullptr;
  T* y = nullptr;
  T* z = nullptr;
};

class Fluid;

// Validates, allocates and sets the rest state rho = 1, u = 0.
// kInvalidArgument for bad params, kResourceExhausted if allocation fails.
StatusOr<Fluid> make_fluid(const FluidParams& params);

class Fluid {
 public:
  Fluid(Fluid&&) = default;
  Fluid& operator=(Fluid&&) = default;

  const FluidParams& params() const { return params_; }
  int nx() const { return params_.nx; }
  int ny() const { return params_.ny; }
  int nz() const { return params_.nz; }
  std::size_t num_nodes() const { return num_nodes_; }
  std::size_t node(int i, int j, int k) const {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(params_.nx) *
               (static_cast<std::size_t>(j) +
                static_cast<std::size_t>(params_.ny) * static_cast<std::size_t>(k));
  }
  std::int64_t time_step() const { return time_step_; }

  // The wall velocities may change between steps (e.g. a ramp); other params not.
  void set_wall_velocities(const std::array<double, 3>& lower, const std::array<double, 3>& upper);
  void set_uniform_force(const std::array<double, 3>& force) { params_.uniform_force = force; }

  // Coupling fields in the storage precision T (must match params().precision;
  // empty views if the field was not requested).
  template <class T>
  VectorField<T> force_field();
  template <class T>
  VectorField<const T> force_field() const;
  template <class T>
  VectorField<const T> velocity_field() const;

  // The per-node phase indices (num_nodes, x innermost; values <=
  // phase_taus.size()); empty without phase_taus. A value above
  // phase_taus.size() is undefined behaviour of the step: set_phases checks.
  std::span<const std::uint8_t> phases() const { return {phases_.data(), phases_.size()}; }

 private:
  friend StatusOr<Fluid> make_fluid(const FluidParams& params);
  friend struct FluidAccess;
  explicit Fluid(const FluidParams& params);

  FluidParams params_;
  std::size_t num_nodes_ = 0;
  std::size_t stride_ = 0;  // elements between consecutive direction arrays (aligned)
  std::int64_t time_step_ = 0;
  // AA pattern: after an odd number of steps the array holds the
  // post-collision populations of the previous step in the opposite slots.
  bool aa_swapped_ = false;
  int current_ = 0;  // two-array scheme: which half holds the populations
  AlignedArray<double> populations_d_, force_d_, velocity_d_, wall_density_d_;
  AlignedArray<float> populations_f_, force_f_, velocity_f_, wall_density_f_;
  AlignedArray<std::uint8_t> phases_;
};

// Copies num_nodes phase indices into the fluid's phase field.
// kFailedPrecondition without a phase field, kInvalidArgument for a wrong
// size or an index above phase_taus.size().
Status set_phases(Fluid& fluid, std::span<const std::uint8_t> phases);

// One fused time step: for every node, moments (with the half-force shift),
// TRT/BGK collision with Guo forcing from the force field (if allocated) plus
// the uniform force, and streaming with periodic wrap and moving-wall
// bounce-back. If the velocity field is allocated it receives the velocity
// u(t) = (sum f c + F/2) / rho of this step, the fluid velocity at the time of
// the forces (what the immersed boundary moves with).
void collide_stream(Fluid& fluid);

// Sets f = f_eq(rho, u) at every node from flat per-node arrays (x innermost,
// num_nodes each); an empty `density` means rho = 1 everywhere.
void set_equilibrium(Fluid& fluid, std::span<const double> density, std::span<const double> ux,
                     std::span<const double> uy, std::span<const double> uz);

void zero_force_field(Fluid& fluid);

// On demand, from the populations of the current time (num_nodes per span).
// The velocity includes the half-force shift with the current force field and
// uniform force. Any output span may be empty to skip it.
void compute_moments(const Fluid& fluid, std::span<double> density, std::span<double> ux,
                     std::span<double> uy, std::span<double> uz);

// Fills the velocity field (if allocated) on demand, e.g. before the first
// step of a coupled run; collide_stream refreshes it afterwards.
void update_velocity_field(Fluid& fluid);

// Total mass sum_x rho(x), accumulated in double.
double total_mass(const Fluid& fluid);

// The 19 populations f_i (not deviations) of node (i, j, k) at the current
// time, before collision, whatever the storage scheme and its phase.
std::array<double, kQ> populations(const Fluid& fluid, int i, int j, int k);

}  // namespace cellflow::lb
