#include "physics/cell/cell_body.h"

#include <algorithm>
#include <string>
#include <utility>

#include "physics/mesh/quadratic_tets.h"
#include "physics/mesh/tet_geometry.h"
#include "physics/observables/shape.h"

namespace cellflow::cell {

StatusOr<CellBody> build_cell_body(const CellParams& cell, elastic::VolumetricTerm volumetric,
                                   std::string_view field_prefix, Centring centring,
                                   const mesh::PoleGrading& pole_grading, elastic::Element element) {
  StatusOr<mesh::TetMesh> built = build_cell_mesh(cell, field_prefix, pole_grading);
  if (!built.ok()) return built.status();
  CellBody out;
  out.mesh = std::move(built).value();
  mesh::TetMesh& m = out.mesh;
  if (m.on_surface.size() != m.num_vertices()) mesh::mark_surface_vertices(m);

  std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (std::size_t v = 0; v < m.num_vertices(); ++v) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], m.positions_m[3 * v + a]);
      hi[a] = std::max(hi[a], m.positions_m[3 * v + a]);
    }
  }
  for (int a = 0; a < 3; ++a) out.extent_m[a] = hi[a] - lo[a];
  const observables::Shape reference = observables::measure_shape(m, m.positions_m.data());
  out.reference_taylor_deformation = reference.taylor_deformation;
  if (centring == Centring::kBoundingBox) {
    // x -= (lo + hi) / 2
    for (std::size_t v = 0; v < m.num_vertices(); ++v) {
      for (int a = 0; a < 3; ++a) m.positions_m[3 * v + a] -= 0.5 * (lo[a] + hi[a]);
    }
  } else {
    // x -= x_c, x_c the volume-weighted centroid
    for (std::size_t v = 0; v < m.num_vertices(); ++v) {
      for (int d = 0; d < 3; ++d) m.positions_m[3 * v + d] -= reference.centroid_m[d];
    }
  }

  if (element == elastic::Element::kQuadraticTet) {
    mesh::MidEdgeProjection projection;
    const bool generated_sphere = cell.mesh_file.empty() && !cell.mesh_bytes;
    if (generated_sphere) projection.sphere_centre_m = std::array<double, 3>{0.0, 0.0, 0.0};
    mesh::add_mid_edge_nodes(m, projection);
  }
  out.materials = {cell.material, cell.nucleus ? cell.nucleus->material : cell.material};
  StatusOr<elastic::ElasticBody> body = elastic::make_elastic_body(m, out.materials, volumetric);
  if (!body.ok()) {
    std::string_view field = field_prefix;
    if (!field.empty() && field.back() == '.') field.remove_suffix(1);
    return Status(body.status().code(), std::string(field) + ": " + body.status().message());
  }
  out.body = std::move(body).value();
  return out;
}

}  // namespace cellflow::cell
