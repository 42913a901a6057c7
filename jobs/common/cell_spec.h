// CellSpec and MaterialSpec (proto/cellflow/v1/cell.proto) -> cell::CellParams,
// shared by the spec conversion of every scene. Unset optional fields take the
// defaults of the physics structs (declared there once; the proto comments
// quote them); the scene passes its own default cell (its default mesh size
// among them).
#pragma once

#include <memory>
#include <string>

#include "cellflow/v1/cell.pb.h"
#include "physics/cell/cell_params.h"

namespace cellflow::jobs {

// Unset fields keep elastic::Material's defaults (nu = 0.48, w = 1), the one
// place they are declared.
inline elastic::Material to_material(const v1::MaterialSpec& m) {
  elastic::Material material;
  material.youngs_modulus_pa = m.youngs_modulus_pa();
  if (m.has_poisson_ratio()) material.poisson_ratio = m.poisson_ratio();
  if (m.has_mooney_rivlin_w()) material.mooney_rivlin_w = m.mooney_rivlin_w();
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
  if (!c.mesh_bytes().empty()) {
    cell.mesh_bytes = std::make_shared<const std::string>(c.mesh_bytes());
    cell.mesh_name = "mesh " + c.mesh_sha256().substr(0, 16);
  }
  return cell;
}

}  // namespace cellflow::jobs
