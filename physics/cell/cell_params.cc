#include "physics/cell/cell_params.h"

#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <string>

#include "physics/mesh/sphere_mesh.h"

namespace cellflow::cell {

namespace {

// A read mesh must describe a cell of about the stated radius: the file is
// read in metres, and a unit-sphere file with R = 8.6e-6 would otherwise give
// a 1 m cell without a word.
constexpr double kMeshRadiusMismatch = 1.25;
// A nucleus is a body inside the cell: from a hundredth of its radius (below
// that no mesh of kMaxSphereVertexCount vertices resolves it) to 0.99 of it
// (a thinner shell cannot hold one layer of tetrahedra).
constexpr double kMinNucleusRadii = 0.01;
constexpr double kMaxNucleusRadii = 0.99;

}  // namespace

Violations check(const CellParams& cell) {
  Violations violations;
  // The sphere mesher's range (0.1 um to 1 cm): a cell outside it cannot be
  // meshed, and no cell is that small or large. Written so that NaN fails.
  const double r = cell.radius_m;
  if (!(r >= mesh::kMinSphereRadiusM && r <= mesh::kMaxSphereRadiusM)) {
    violations.add_value("radius_m", r,
                         "lie in [" + number_text(mesh::kMinSphereRadiusM) + ", " +
                             number_text(mesh::kMaxSphereRadiusM) + "] (0.1 um to 1 cm)");
  }
  violations.add_all(elastic::check(cell.material), "material.");
  if (cell.nucleus) {
    const double rn = cell.nucleus->radius_m;
    if (!(rn > 0.0 && rn < cell.radius_m)) {
      violations.add_value("nucleus.radius_m", rn,
                           "lie in (0, radius_m) = (0, " + number_text(cell.radius_m) + ")");
    } else if (!(rn >= kMinNucleusRadii * cell.radius_m && rn <= kMaxNucleusRadii * cell.radius_m)) {
      violations.add_value("nucleus.radius_m", rn,
                           "lie in [" + number_text(kMinNucleusRadii) + " radius_m, " +
                               number_text(kMaxNucleusRadii) + " radius_m] = [" +
                               number_text(kMinNucleusRadii * cell.radius_m) + ", " +
                               number_text(kMaxNucleusRadii * cell.radius_m) + "]");
    }
    violations.add_all(elastic::check(cell.nucleus->material), "nucleus.material.");
  }
  if (cell.mesh_bytes) {
    // Read (bounded) by build_cell_mesh; nothing on disk to check.
  } else if (cell.mesh_file.empty()) {
    if (cell.target_vertex_count < mesh::kMinSphereVertexCount ||
        cell.target_vertex_count > mesh::kMaxSphereVertexCount) {
      violations.add("target_vertex_count", "= " + std::to_string(cell.target_vertex_count) +
                                                " must lie in [" +
                                                std::to_string(mesh::kMinSphereVertexCount) + ", " +
                                                std::to_string(mesh::kMaxSphereVertexCount) + "]");
    }
  } else {
    // stat, never open: opening a FIFO blocks, and a device never ends.
    struct stat info {};
    if (::stat(cell.mesh_file.c_str(), &info) != 0 || !S_ISREG(info.st_mode)) {
      violations.add("mesh_file", "= '" + cell.mesh_file + "' is not a readable regular file");
    }
  }
  return violations;
}

Status validate(const CellParams& cell, std::string_view field_prefix) {
  return check(cell).status(field_prefix);
}

StatusOr<mesh::TetMesh> build_cell_mesh(const CellParams& cell, std::string_view field_prefix,
                                        const mesh::PoleGrading& pole_grading) {
  if (Status s = validate(cell, field_prefix); !s.ok()) return s;
  const std::string field = cell.mesh_bytes
                                ? std::string(field_prefix) + "mesh_sha256" +
                                      (cell.mesh_name.empty() ? "" : " (" + cell.mesh_name + ")")
                                : std::string(field_prefix) + "mesh_file '" + cell.mesh_file + "'";
  if (!cell.mesh_bytes && cell.mesh_file.empty()) {
    mesh::SphereMeshOptions options;
    options.radius_m = cell.radius_m;
    options.target_vertex_count = cell.target_vertex_count;
    if (cell.nucleus) options.nucleus_radius_m = cell.nucleus->radius_m;
    options.pole_grading = pole_grading;
    StatusOr<mesh::TetMesh> made = mesh::make_sphere_mesh(options);
    if (!made.ok()) {
      return Status(made.status().code(),
                    std::string(field_prefix) +
                        "target_vertex_count: sphere meshing failed: " + made.status().message());
    }
    return made;
  }
  StatusOr<mesh::TetMesh> read =
      cell.mesh_bytes ? mesh::read_gmsh_msh_from_bytes(*cell.mesh_bytes,
                                                       cell.mesh_name.empty() ? "mesh" : cell.mesh_name, 1.0)
                      : mesh::read_gmsh_msh(cell.mesh_file, 1.0);
  if (!read.ok()) {
    return Status(read.status().code(), field + ": " + read.status().message());
  }
  const mesh::MeshQuality quality = mesh::mesh_quality(*read);
  // radius of the sphere with the mesh's volume
  const double equivalent_radius = std::cbrt(3.0 * quality.volume_m3 / (4.0 * M_PI));
  if (!(equivalent_radius < kMeshRadiusMismatch * cell.radius_m &&
        equivalent_radius > cell.radius_m / kMeshRadiusMismatch)) {
    return invalid_argument(field + ": the mesh's volume-equivalent radius " +
                            number_text(equivalent_radius) +
                            " m does not match cell.radius_m = " + number_text(cell.radius_m) + " m (" +
                            std::string(field_prefix) + "radius_m) within a factor " +
                            number_text(kMeshRadiusMismatch) + " (file coordinates are read in metres)");
  }
  bool has_nucleus = false;
  for (const mesh::Region r : read->tet_region) has_nucleus = has_nucleus || r == mesh::Region::kNucleus;
  if (cell.nucleus && !has_nucleus) {
    return invalid_argument(std::string(field_prefix) + "nucleus is set but " + field +
                            " marks no nucleus tetrahedra (physical group \"nucleus\" or tag 2)");
  }
  return read;
}

}  // namespace cellflow::cell
