// Tetrahedral cell mesh: reference vertex positions and connectivity as flat
// arrays. Positions are SI metres, interleaved x0 y0 z0 x1 y1 z1 ...; each
// tetrahedron is four vertex indices with positive reference orientation
// (det[x1-x4, x2-x4, x3-x4] > 0, the ordering of paper eq. 11-12, vertex 4 the
// origin of the local coordinates).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cellflow::mesh {

// Region of a tetrahedron; the force calculation is local (paper section 3.1)
// so each region may carry its own material.
enum class Region : std::uint8_t { kCytoplasm = 0, kNucleus = 1 };

struct TetMesh {
  std::vector<double> positions_m;       // 3 * num_vertices()
  std::vector<std::int32_t> tets;        // 4 * num_tets()
  std::vector<Region> tet_region;        // num_tets(); all kCytoplasm without a nucleus
  std::vector<std::uint8_t> on_surface;  // num_vertices(); 1 for boundary vertices
  // Quadratic (10-node) tetrahedra, empty for the linear mesh: 10 node indices
  // per tet in VTK order (physics/mesh/quadratic_tets.h), the first four the
  // corners of `tets`, then the mid-edge nodes (appended after the corner
  // vertices in positions_m), so everything that reads `tets` sees the
  // straight-sided corner mesh.
  std::vector<std::int32_t> quadratic_tets;

  std::size_t num_vertices() const { return positions_m.size() / 3; }
  std::size_t num_tets() const { return tets.size() / 4; }
};

}  // namespace cellflow::mesh
