// Mesh-quality report: dihedral angles, radius-edge ratio, volumes, edge
// lengths. Not a hot path; clarity over speed.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"

namespace cellflow::mesh {
MeshQuality mesh_quality(const TetMesh& mesh) {
  MeshQuality q;
  q.num_vertices = mesh.num_vertices();
  q.num_tets = mesh.num_tets();
  for (std::uint8_t s : mesh.on_surface) q.num_surface_vertices += s != 0 ? 1 : 0;
  if (q.num_tets == 0) return q;

  q.min_dihedral_deg = 180.0;
  q.max_dihedral_deg = 0.0;
  q.min_tet_volume_m3 = std::numeric_limits<double>::infinity();
  std::vector<std::pair<std::int32_t, std::int32_t>> edges;
  edges.reserve(6 * q.num_tets);

  for (std::size_t t = 0; t < q.num_tets; ++t) {
    const std::int32_t* tet = &mesh.tets[4 * t];
    const double volume = tet_signed_volume(mesh.positions_m.data(), tet);
    q.volume_m3 += volume;
    q.min_tet_volume_m3 = std::min(q.min_tet_volume_m3, volume);

    const DihedralRange dihedral = tet_dihedral_range(mesh.positions_m.data(), tet);
    q.min_dihedral_deg = std::min(q.min_dihedral_deg, dihedral.min_deg);
    q.max_dihedral_deg = std::max(q.max_dihedral_deg, dihedral.max_deg);

    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) edges.emplace_back(std::min(tet[a], tet[b]), std::max(tet[a], tet[b]));
    }
    q.max_radius_edge_ratio =
        std::max(q.max_radius_edge_ratio, tet_radius_edge_ratio(mesh.positions_m.data(), tet));
  }

  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  double total_length = 0.0;
  for (const auto& [a, b] : edges) {
    const double* xa = &mesh.positions_m[3 * static_cast<std::size_t>(a)];
    const double* xb = &mesh.positions_m[3 * static_cast<std::size_t>(b)];
    total_length += std::sqrt((xa[0] - xb[0]) * (xa[0] - xb[0]) + (xa[1] - xb[1]) * (xa[1] - xb[1]) +
                              (xa[2] - xb[2]) * (xa[2] - xb[2]));
  }
  q.mean_edge_length_m = total_length / static_cast<double>(edges.size());
  return q;
}

}  // namespace cellflow::mesh
