// Construction and storage of the fluid: parameter validation, the memory
// estimate, allocation of the lattice (make_fluid) and access to the coupling
// fields (force_field, velocity_field, zero_force_field). The step is in
// fluid_step.cc, the moments in fluid_moments.cc.
#include "physics/lb/fluid.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <new>
#include <string>
#include <type_traits>

#include "physics/lb/fluid_internal.h"

namespace cellflow::lb {

namespace {

std::string format_double(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

Status validate(const FluidParams& p) {
  if (p.nx < 1 || p.ny < 1 || p.nz < 1) {
    return invalid_argument("lb: lattice size " + std::to_string(p.nx) + " x " + std::to_string(p.ny) +
                            " x " + std::to_string(p.nz) + " must be at least 1 node per direction");
  }
  if (!(p.tau > 0.5) || !std::isfinite(p.tau)) {
    return invalid_argument("lb: tau = " + format_double(p.tau) + " must lie in (0.5, inf)");
  }
  if (p.collision == CollisionModel::kTrt && (!(p.trt_magic > 0.0) || !std::isfinite(p.trt_magic))) {
    return invalid_argument("lb: trt_magic = " + format_double(p.trt_magic) + " must lie in (0, inf)");
  }
  if (p.walls_y && (p.lower_wall_velocity[1] != 0.0 || p.upper_wall_velocity[1] != 0.0)) {
    return invalid_argument("lb: wall velocities must be tangential (y component 0)");
  }
  for (int d = 0; d < 3; ++d) {
    if (!std::isfinite(p.lower_wall_velocity[d]) || !std::isfinite(p.upper_wall_velocity[d]) ||
        !std::isfinite(p.uniform_force[d])) {
      return invalid_argument("lb: wall velocities and uniform_force must be finite");
    }
  }
  if (p.phase_taus.size() > static_cast<std::size_t>(kMaxPhases)) {
    return invalid_argument("lb: phase_taus has " + std::to_string(p.phase_taus.size()) +
                            " entries, at most " + std::to_string(kMaxPhases));
  }
  for (std::size_t i = 0; i < p.phase_taus.size(); ++i) {
    if (!(p.phase_taus[i] > 0.5) || !std::isfinite(p.phase_taus[i])) {
      return invalid_argument("lb: phase_taus[" + std::to_string(i) +
                              "] = " + format_double(p.phase_taus[i]) + " must lie in (0.5, inf)");
    }
  }
  if (p.threads < 0) return invalid_argument("lb: threads = " + std::to_string(p.threads) + " must be >= 0");
  if (!simd_supported(p.simd)) {
    return invalid_argument("lb: simd = " + std::string(simd_name(p.simd)) +
                            " is not supported by this CPU (best: " + std::string(simd_name(best_simd())) +
                            ")");
  }
  return Status::ok_status();
}

std::size_t memory_bytes(const FluidParams& p) {
  const std::size_t nodes = static_cast<std::size_t>(std::max(p.nx, 0)) * std::max(p.ny, 0) *
                            static_cast<std::size_t>(std::max(p.nz, 0));
  const std::size_t stride = direction_stride(nodes);
  const std::size_t value = p.precision == Precision::kFloat ? sizeof(float) : sizeof(double);
  std::size_t arrays = kQ * (p.streaming == Streaming::kTwoArray ? 2 : 1);
  if (p.force_field) arrays += 3;
  if (p.velocity_field) arrays += 3;
  return arrays * stride * value + wall_density_size(p) * value + (p.phase_taus.empty() ? 0 : nodes);
}

Fluid::Fluid(const FluidParams& params)
    : params_(params),
      num_nodes_(static_cast<std::size_t>(params.nx) * params.ny * static_cast<std::size_t>(params.nz)),
      stride_(direction_stride(num_nodes_)) {}

StatusOr<Fluid> make_fluid(const FluidParams& params) {
  if (Status s = validate(params); !s.ok()) return s;
  Fluid fluid(params);
  const std::size_t pops = kQ * fluid.stride_ * (params.streaming == Streaming::kTwoArray ? 2 : 1);
  const std::size_t field = 3 * fluid.stride_;
  try {
    // All zero = deviations of the rest state rho = 1, u = 0 (and zero fields).
    if (params.precision == Precision::kDouble) {
      fluid.populations_d_ = AlignedArray<double>(pops);
      fluid.wall_density_d_ = AlignedArray<double>(wall_density_size(params));
      if (params.force_field) fluid.force_d_ = AlignedArray<double>(field);
      if (params.velocity_field) fluid.velocity_d_ = AlignedArray<double>(field);
    } else {
      fluid.populations_f_ = AlignedArray<float>(pops);
      fluid.wall_density_f_ = AlignedArray<float>(wall_density_size(params));
      if (params.force_field) fluid.force_f_ = AlignedArray<float>(field);
      if (params.velocity_field) fluid.velocity_f_ = AlignedArray<float>(field);
    }
    if (!params.phase_taus.empty()) fluid.phases_ = AlignedArray<std::uint8_t>(fluid.num_nodes_);
  } catch (const std::bad_alloc&) {
    return Status(StatusCode::kResourceExhausted,
                  "lb: cannot allocate " + std::to_string(memory_bytes(params)) + " bytes for the lattice");
  }
  return fluid;
}

void Fluid::set_wall_velocities(const std::array<double, 3>& lower, const std::array<double, 3>& upper) {
  params_.lower_wall_velocity = lower;
  params_.upper_wall_velocity = upper;
}

template <class T>
VectorField<T> Fluid::force_field() {
  AlignedArray<T>& f = FluidAccess::force<T>(*this);
  if (f.empty()) return {};
  return {f.data(), f.data() + stride_, f.data() + 2 * stride_};
}

template <class T>
VectorField<const T> Fluid::force_field() const {
  const AlignedArray<T>& f = FluidAccess::force<T>(*this);
  if (f.empty()) return {};
  return {f.data(), f.data() + stride_, f.data() + 2 * stride_};
}

template <class T>
VectorField<const T> Fluid::velocity_field() const {
  const AlignedArray<T>& u = FluidAccess::velocity<T>(*this);
  if (u.empty()) return {};
  return {u.data(), u.data() + stride_, u.data() + 2 * stride_};
}

template VectorField<double> Fluid::force_field<double>();
template VectorField<float> Fluid::force_field<float>();
template VectorField<const double> Fluid::force_field<double>() const;
template VectorField<const float> Fluid::force_field<float>() const;
template VectorField<const double> Fluid::velocity_field<double>() const;
template VectorField<const float> Fluid::velocity_field<float>() const;

Status set_phases(Fluid& fluid, std::span<const std::uint8_t> phases) {
  AlignedArray<std::uint8_t>& field = FluidAccess::phases(fluid);
  if (field.empty())
    return Status(StatusCode::kFailedPrecondition, "lb: the fluid has no phase field (phase_taus)");
  if (phases.size() != fluid.num_nodes()) {
    return invalid_argument("lb: " + std::to_string(phases.size()) + " phases for " +
                            std::to_string(fluid.num_nodes()) + " nodes");
  }
  const std::uint8_t max_phase = static_cast<std::uint8_t>(fluid.params().phase_taus.size());
  for (std::uint8_t v : phases) {
    if (v > max_phase) {
      return invalid_argument("lb: phase " + std::to_string(v) + " above the " + std::to_string(max_phase) +
                              " phase_taus");
    }
  }
  std::copy(phases.begin(), phases.end(), field.data());
  return Status::ok_status();
}

void zero_force_field(Fluid& fluid) {
  if (!fluid.params().force_field) return;
  const auto zero = [&](auto& arr) {
    using T = std::remove_reference_t<decltype(arr[0])>;
    T* d = arr.data();
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(arr.size());
#pragma omp parallel for schedule(static) num_threads(thread_count(fluid.params()))
    for (std::ptrdiff_t i = 0; i < n; ++i) d[i] = T(0);
  };
  if (fluid.params().precision == Precision::kDouble)
    zero(FluidAccess::force<double>(fluid));
  else
    zero(FluidAccess::force<float>(fluid));
}

}  // namespace cellflow::lb
