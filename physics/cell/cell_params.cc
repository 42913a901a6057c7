#include "physics/cell/cell_params.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <string>

#include "physics/mesh/sphere_mesh.h"

namespace cellflow::cell {

namespace {

std::string format_number(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

void add_violation(std::string& message, std::string_view text) {
  if (!message.empty()) message += "; ";
  message += text;
}

// A read mesh must describe a cell of about the stated radius: the file is
// read in metres, and a unit-sphere file with R = 8.6e-6 would otherwise give
// a 1 m cell without a word.
constexpr double kMeshRadiusMismatch = 1.25;

}  // namespace

Status validate(const CellParams& cell, std::string_view field_prefix) {
  const std::string prefix(field_prefix);
  std::string message;
  if (!(cell.radius_m > 0.0 && std::isfinite(cell.radius_m))) {
    add_violation(message, prefix + "radius_m = " + format_number(cell.radius_m) + " must be > 0 and finite");
  }
  if (Status s = elastic::validate(cell.material, prefix + "material."); !s.ok()) {
    add_violation(message, s.message());
  }
  if (cell.nucleus) {
    const double rn = cell.nucleus->radius_m;
    if (!(rn > 0.0 && rn < cell.radius_m)) {
      add_violation(message, prefix + "nucleus.radius_m = " + format_number(rn) +
                                 " must lie in (0, radius_m) = (0, " + format_number(cell.radius_m) + ")");
    }
    if (Status s = elastic::validate(cell.nucleus->material, prefix + "nucleus.material."); !s.ok()) {
      add_violation(message, s.message());
    }
  }
  if (cell.mesh_file.empty()) {
    if (cell.target_vertex_count < 200 || cell.target_vertex_count > 20000) {
      add_violation(message, prefix + "target_vertex_count = " + std::to_string(cell.target_vertex_count) +
                                 " must lie in [200, 20000]");
    }
  } else if (!std::ifstream(cell.mesh_file).good()) {
    add_violation(message, prefix + "mesh_file = '" + cell.mesh_file + "' cannot be opened for reading");
  }
  if (message.empty()) return Status::ok_status();
  return invalid_argument(std::move(message));
}

StatusOr<mesh::TetMesh> build_cell_mesh(const CellParams& cell, std::string_view field_prefix) {
  if (Status s = validate(cell, field_prefix); !s.ok()) return s;
  const std::string field = std::string(field_prefix) + "mesh_file '" + cell.mesh_file + "'";
  if (cell.mesh_file.empty()) {
    mesh::SphereMeshOptions options;
    options.radius_m = cell.radius_m;
    options.target_vertex_count = cell.target_vertex_count;
    if (cell.nucleus) options.nucleus_radius_m = cell.nucleus->radius_m;
    StatusOr<mesh::TetMesh> made = mesh::make_sphere_mesh(options);
    if (!made.ok()) {
      return Status(made.status().code(),
                    std::string(field_prefix) +
                        "target_vertex_count: sphere meshing failed: " + made.status().message());
    }
    return made;
  }
  StatusOr<mesh::TetMesh> read = mesh::read_gmsh_msh(cell.mesh_file, 1.0);
  if (!read.ok()) {
    return Status(read.status().code(), field + ": " + read.status().message());
  }
  const mesh::MeshQuality quality = mesh::mesh_quality(*read);
  // radius of the sphere with the mesh's volume
  const double equivalent_radius = std::cbrt(3.0 * quality.volume_m3 / (4.0 * M_PI));
  if (!(equivalent_radius < kMeshRadiusMismatch * cell.radius_m &&
        equivalent_radius > cell.radius_m / kMeshRadiusMismatch)) {
    return invalid_argument(field + ": the mesh's volume-equivalent radius " +
                            format_number(equivalent_radius) +
                            " m does not match cell.radius_m = " + format_number(cell.radius_m) + " m (" +
                            std::string(field_prefix) + "radius_m) within a factor " +
                            format_number(kMeshRadiusMismatch) + " (file coordinates are read in metres)");
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
