#include "physics/lb/fluid_state.h"

#include "physics/lb/fluid_internal.h"

namespace cellflow::lb {

namespace {

template <class T>
std::span<std::byte> bytes_of(AlignedArray<T>& array) {
  return {reinterpret_cast<std::byte*>(array.data()), array.size() * sizeof(T)};
}

template <class T>
std::span<const std::byte> bytes_of(const AlignedArray<T>& array) {
  return {reinterpret_cast<const std::byte*>(array.data()), array.size() * sizeof(T)};
}

bool is_float(const Fluid& fluid) {
  return fluid.params().precision == Precision::kFloat;
}

}  // namespace

FluidPhase fluid_phase(const Fluid& fluid) {
  FluidPhase phase;
  phase.time_step = fluid.time_step();
  phase.aa_swapped = FluidAccess::aa_swapped(fluid);
  phase.current = FluidAccess::current(fluid);
  return phase;
}

Status set_fluid_phase(Fluid& fluid, const FluidPhase& phase) {
  if (phase.time_step < 0) return invalid_argument("fluid phase: time_step must be >= 0");
  if (phase.current != 0 && phase.current != 1)
    return invalid_argument("fluid phase: current must be 0 or 1");
  FluidAccess::time_step(fluid) = phase.time_step;
  FluidAccess::aa_swapped(fluid) = phase.aa_swapped;
  FluidAccess::current(fluid) = phase.current;
  return {};
}

std::span<const std::byte> population_bytes(const Fluid& fluid) {
  return is_float(fluid) ? bytes_of(FluidAccess::populations<float>(fluid))
                         : bytes_of(FluidAccess::populations<double>(fluid));
}

std::span<std::byte> mutable_population_bytes(Fluid& fluid) {
  return is_float(fluid) ? bytes_of(FluidAccess::populations<float>(fluid))
                         : bytes_of(FluidAccess::populations<double>(fluid));
}

std::span<const std::byte> wall_density_bytes(const Fluid& fluid) {
  return is_float(fluid) ? bytes_of(FluidAccess::wall_density<float>(fluid))
                         : bytes_of(FluidAccess::wall_density<double>(fluid));
}

std::span<std::byte> mutable_wall_density_bytes(Fluid& fluid) {
  return is_float(fluid) ? bytes_of(FluidAccess::wall_density<float>(fluid))
                         : bytes_of(FluidAccess::wall_density<double>(fluid));
}

}  // namespace cellflow::lb
