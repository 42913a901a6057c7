#include "jobs/shear_flow/shear_flow_spec.h"

#include <string>

#include "jobs/common/cell_spec.h"
#include "physics/core/violations.h"

namespace cellflow::jobs {
StatusOr<scenes::ShearFlowParams> convert(const v1::ShearFlowSpec& spec, std::string_view field_prefix) {
  const std::string prefix(field_prefix);
  if (!spec.has_cell()) return invalid_argument(prefix + "cell must be set");
  if (!spec.cell().has_material()) return invalid_argument(prefix + "cell.material must be set");
  scenes::ShearFlowParams params;
  params.cell = to_cell(spec.cell(), scenes::flow_cell_defaults());
  // Unset: the struct's defaults (water, paper section 7.1).
  if (spec.has_fluid_density_kg_m3()) params.fluid_density_kg_m3 = spec.fluid_density_kg_m3();
  if (spec.has_fluid_viscosity_pa_s()) params.fluid_viscosity_pa_s = spec.fluid_viscosity_pa_s();
  switch (spec.drive_case()) {
    case v1::ShearFlowSpec::kShearRatePerS:
      params.shear_rate_per_s = spec.shear_rate_per_s();
      // An explicit 0 reads as "set": say so rather than "set one of".
      if (params.shear_rate_per_s == 0.0)
        return invalid_argument(prefix + "shear_rate_per_s = 0 must be > 0");
      break;
    case v1::ShearFlowSpec::kCapillaryNumber:
      params.capillary_number = spec.capillary_number();
      if (params.capillary_number == 0.0)
        return invalid_argument(prefix + "capillary_number = 0 must be > 0");
      break;
    case v1::ShearFlowSpec::DRIVE_NOT_SET:
      return invalid_argument("set one of " + prefix + "shear_rate_per_s (> 0) or " + prefix +
                              "capillary_number (> 0)");
  }

  // Unset: 1 (no contrast, nothing marked); the range is checked by validate().
  if (spec.has_viscosity_ratio()) params.viscosity_ratio = spec.viscosity_ratio();

  if (Status numerics = convert_numerics(spec.numerics(), params.numerics, prefix + "numerics.");
      !numerics.ok())
    return numerics;
  return params;
}

Status convert_numerics(const v1::ShearFlowNumerics& in, scenes::ShearFlowNumerics& n,
                        std::string_view field_prefix) {
  const std::string prefix(field_prefix);
  if (in.has_cells_per_radius()) n.cells_per_radius = in.cells_per_radius();
  if (in.has_box_x_radii()) n.box_x_radii = in.box_x_radii();
  if (in.has_box_y_radii()) n.box_y_radii = in.box_y_radii();
  if (in.has_box_z_radii()) n.box_z_radii = in.box_z_radii();
  if (in.has_relaxation_time()) n.relaxation_time = in.relaxation_time();
  if (in.has_max_mach()) n.max_mach = in.max_mach();
  if (in.has_max_time_s()) n.max_time_s = in.max_time_s();
  if (in.has_steady_tolerance()) n.steady_tolerance = in.steady_tolerance();
  if (in.has_steady_window_strain()) n.steady_window_strain = in.steady_window_strain();
  if (in.has_ibm_kernel()) {
    StatusOr<ibm::Kernel> kernel = ibm::parse_kernel(in.ibm_kernel(), prefix + "ibm_kernel");
    if (!kernel.ok()) return kernel.status();
    n.ibm_kernel = *kernel;
  }
  if (in.has_single_precision()) n.single_precision = in.single_precision();
  if (in.has_elastic_single_precision()) n.elastic_single_precision = in.elastic_single_precision();
  if (in.has_sample_every_strain()) n.sample_every_strain = in.sample_every_strain();
  if (in.has_snapshot_every_strain()) n.snapshot_every_strain = in.snapshot_every_strain();
  if (in.has_fluid_snapshots()) n.fluid_snapshots = in.fluid_snapshots();
  if (in.has_memory_limit_bytes()) n.memory_limit_bytes = in.memory_limit_bytes();
  if (in.has_target_reynolds_number()) n.target_reynolds_number = in.target_reynolds_number();
  if (in.has_max_strain()) n.max_strain = in.max_strain();
  if (in.has_max_stiffness_ratio()) n.max_stiffness_ratio = in.max_stiffness_ratio();
  if (in.has_hydrodynamic_radius_offset()) {
    // Negative values are the physics layer's "kernel default"; a spec says that by leaving it unset.
    if (!(in.hydrodynamic_radius_offset() >= 0.0)) {
      return invalid_argument(
          prefix + "hydrodynamic_radius_offset = " + number_text(in.hydrodynamic_radius_offset(), 6) +
          " must lie in [0, 2] lattice spacings (unset: the kernel's value)");
    }
    n.hydrodynamic_radius_offset = in.hydrodynamic_radius_offset();
  }
  if (in.has_resolve_thickness()) n.resolve_thickness = in.resolve_thickness();
  if (in.has_boundaries()) {
    StatusOr<scenes::ShearFlowBoundaries> boundaries =
        scenes::parse_boundaries(in.boundaries(), prefix + "boundaries");
    if (!boundaries.ok()) return boundaries.status();
    n.boundaries = *boundaries;
  }
  if (in.volumetric_term() == v1::VOLUMETRIC_TERM_PER_TET) {
    n.volumetric = elastic::VolumetricTerm::kPerTet;
  } else if (in.volumetric_term() == v1::VOLUMETRIC_TERM_NODAL_AVERAGE) {
    n.volumetric = elastic::VolumetricTerm::kNodalAverage;
  }
  return Status();
}

StatusOr<scenes::ShearFlowParams> to_params(const v1::ShearFlowSpec& spec, std::string_view field_prefix) {
  StatusOr<scenes::ShearFlowParams> params = convert(spec, field_prefix);
  if (!params.ok()) return params;
  // Fields, ranges, Mach number and memory; the stability check needs the
  // mesh and runs at the start of run_shear_flow.
  const StatusOr<scenes::ShearFlowSetup> plan = scenes::plan_shear_flow(*params, field_prefix);
  if (!plan.ok()) return plan.status();
  return params;
}

Status validate(const v1::ShearFlowSpec& spec, std::string_view field_prefix) {
  return to_params(spec, field_prefix).status();
}

}  // namespace cellflow::jobs
