#include "jobs/suspension/suspension_spec.h"

#include <string>

#include "jobs/common/cell_spec.h"
#include "jobs/shear_flow/shear_flow_spec.h"

namespace cellflow::jobs {
namespace {

scenes::CellPlacement to_placement(const v1::CellPlacement& p) {
  scenes::CellPlacement placement;
  placement.centre_m = {p.x_m(), p.y_m(), p.z_m()};
  placement.rotation_rad = {p.rotation_x_rad(), p.rotation_y_rad(), p.rotation_z_rad()};
  return placement;
}

}  // namespace

Status with_proto_field_names(Status status, std::string_view field_prefix) {
  if (status.ok()) return status;
  const std::string from = std::string(field_prefix) + "kinds[";
  const std::string to = std::string(field_prefix) + "cells[";
  std::string message = status.message();
  for (std::size_t at = message.find(from); at != std::string::npos; at = message.find(from, at + to.size()))
    message.replace(at, from.size(), to);
  return Status(status.code(), message);
}

StatusOr<scenes::SuspensionParams> convert(const v1::SuspensionSpec& spec, std::string_view field_prefix) {
  const std::string prefix(field_prefix);
  if (spec.cells_size() == 0)
    return invalid_argument(prefix + "cells: at least one kind of cell must be set");
  if (spec.cells_size() > kMaxSuspendedKinds) {
    return invalid_argument(prefix + "cells: " + std::to_string(spec.cells_size()) + " kinds, at most " +
                            std::to_string(kMaxSuspendedKinds));
  }
  scenes::SuspensionParams params;
  // A suspended cell's default mesh is coarser than the single cell's: N cells share the step.
  const cell::CellParams defaults = scenes::suspension_cell_defaults();
  for (int k = 0; k < spec.cells_size(); ++k) {
    const v1::SuspendedCells& in = spec.cells(k);
    const std::string field = prefix + "cells[" + std::to_string(k) + "].";
    if (!in.has_cell()) return invalid_argument(field + "cell must be set");
    if (!in.cell().has_material()) return invalid_argument(field + "cell.material must be set");
    scenes::SuspendedCellKind kind;
    kind.cell = to_cell(in.cell(), defaults);
    if (in.has_viscosity_ratio()) kind.viscosity_ratio = in.viscosity_ratio();
    kind.count = in.count();
    kind.volume_fraction = in.volume_fraction();
    kind.placements.reserve(static_cast<std::size_t>(in.placements_size()));
    for (const v1::CellPlacement& p : in.placements()) kind.placements.push_back(to_placement(p));
    params.kinds.push_back(std::move(kind));
  }
  // Unset: the struct's defaults (water).
  if (spec.has_fluid_density_kg_m3()) params.fluid_density_kg_m3 = spec.fluid_density_kg_m3();
  if (spec.has_fluid_viscosity_pa_s()) params.fluid_viscosity_pa_s = spec.fluid_viscosity_pa_s();
  switch (spec.drive_case()) {
    case v1::SuspensionSpec::kShearRatePerS:
      params.shear_rate_per_s = spec.shear_rate_per_s();
      // An explicit 0 reads as "set": say so rather than "set one of".
      if (params.shear_rate_per_s == 0.0)
        return invalid_argument(prefix + "shear_rate_per_s = 0 must be > 0");
      break;
    case v1::SuspensionSpec::kCapillaryNumber:
      params.capillary_number = spec.capillary_number();
      if (params.capillary_number == 0.0)
        return invalid_argument(prefix + "capillary_number = 0 must be > 0");
      break;
    case v1::SuspensionSpec::DRIVE_NOT_SET:
      return invalid_argument("set one of " + prefix + "shear_rate_per_s (> 0) or " + prefix +
                              "capillary_number (> 0)");
  }

  const v1::SuspensionNumerics& in = spec.numerics();
  scenes::SuspensionNumerics& n = params.numerics;  // holds the suspension's defaults
  if (Status flow = convert_numerics(in.flow(), n.flow, prefix + "numerics.flow."); !flow.ok()) return flow;
  if (in.has_seed()) n.seed = in.seed();
  if (in.has_contact_range_dx()) n.contact_range_dx = in.contact_range_dx();
  if (in.has_contact_strength()) n.contact_strength = in.contact_strength();
  if (in.has_average_after_strain()) n.average_after_strain = in.average_after_strain();
  if (in.has_target_standard_error()) n.target_standard_error = in.target_standard_error();
  if (in.has_marking_every_steps()) n.marking_every_steps = in.marking_every_steps();
  if (in.has_min_gap_dx()) n.min_gap_dx = in.min_gap_dx();
  return params;
}

StatusOr<scenes::PlannedSuspension> plan(const v1::SuspensionSpec& spec, std::string_view field_prefix) {
  StatusOr<scenes::SuspensionParams> params = convert(spec, field_prefix);
  if (!params.ok()) return params.status();
  StatusOr<scenes::PlannedSuspension> planned = scenes::plan_suspension_run(*params, field_prefix);
  if (!planned.ok()) return with_proto_field_names(planned.status(), field_prefix);
  return planned;
}

}  // namespace cellflow::jobs
