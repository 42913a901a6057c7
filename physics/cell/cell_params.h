// Parameters shared by every scene: the cell (radius, material, optional
// nucleus, mesh) in SI units. Field names follow proto/cellflow/v1/spec.proto.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "physics/core/status.h"
#include "physics/core/violations.h"
#include "physics/elastic/material.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::cell {

struct NucleusParams {
  double radius_m = 0.0;  // concentric; 0 < radius_m < cell radius
  elastic::Material material;
};

struct CellParams {
  double radius_m = 0.0;
  elastic::Material material;
  std::optional<NucleusParams> nucleus;
  int target_vertex_count = mesh::kDefaultSphereVertexCount;  // sphere mesh size, 200 ... 20000
  std::string mesh_file;  // optional Gmsh .msh v4 ASCII; replaces the generated sphere
  // Optional Gmsh .msh v4 ASCII bytes (an uploaded mesh); replaces the
  // generated sphere and mesh_file. Read with the bounded reader; mesh_name
  // stands for the file in messages (e.g. the mesh's hash).
  std::shared_ptr<const std::string> mesh_bytes;
  std::string mesh_name;
};

// Every field out of range, named relative to the cell ("radius_m",
// "material.poisson_ratio") with its allowed range; a mesh_file must be a
// regular file (checked with stat, never opened here); mesh_bytes are not
// looked at here (build_cell_mesh reads them).
Violations check(const CellParams& cell);
// check(cell) as a Status, every field under field_prefix.
Status validate(const CellParams& cell, std::string_view field_prefix);

// Builds (or reads) the cell mesh for `cell`: a TetGen sphere of
// target_vertex_count vertices, or the Gmsh bytes mesh_bytes (field
// "mesh_sha256"), or the Gmsh file mesh_file read in metres
// (its volume-equivalent radius must match radius_m within a factor 1.25;
// nucleus tetrahedra of a file take the cytoplasm material unless `nucleus`
// is set). Errors of the mesher and the reader are carried through with the
// field path `field_prefix` + "mesh_file" prepended. `pole_grading` grades a
// generated sphere towards its poles (mesh::PoleGrading; files and uploaded
// meshes are taken as they are).
StatusOr<mesh::TetMesh> build_cell_mesh(const CellParams& cell, std::string_view field_prefix = "cell.",
                                        const mesh::PoleGrading& pole_grading = {});

}  // namespace cellflow::cell
