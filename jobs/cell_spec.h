// CellSpec and MaterialSpec (proto/cellflow/v1/cell.proto) -> cell::CellParams,
// shared by the spec conversion of every scene. Unset optional fields take the
// defaults the proto documents; the scene passes its own default cell (its
// default mesh size among them). Header-only: spec/shear_flow is its own
// target and does not link cellflow::spec.
#pragma once

#include "cellflow/v1/cell.pb.h"
#include "physics/cell/cell_params.h"

namespace cellflow::jobs {

inline constexpr double kDefaultPoissonRatio = 0.48;
inline constexpr double kDefaultMooneyRivlinW = 1.0;

inline elastic::Material to_material(const v1::MaterialSpec& m) {
  elastic::Material material;
  material.youngs_modulus_pa = m.youngs_modulus_pa();
  material.poisson_ratio = m.has_poisson_ratio() ? m.poisson_ratio() : kDefaultPoissonRatio;
  material.mooney_rivlin_w = m.has_mooney_rivlin_w() ? m.mooney_rivlin_w() : kDefaultMooneyRivlinW;
  return material;
}

// The fields of `c` over `cell`, which holds the scene's defaults.
inline cell::CellParams to_cell(const v1::CellSpec& c, cell::CellParams cell) {
  cell.radius_m = c.radius_m();
  cell.material = to_material(c.material());
  if (c.has_nucleus()) {
    cell.nucleus = cell::NucleusParams{c.nucleus().radius_m(), to_material(c.nucleus().material())};
  }
  if (c.has_target_vertex_count()) cell.target_vertex_count = c.target_vertex_count();
  cell.mesh_file = c.mesh_file();
  return cell;
}

}  // namespace cellflow::jobs
