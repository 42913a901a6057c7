#include "physics/mesh/tet_geometry.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace cellflow::mesh {

DihedralRange tet_dihedral_range(const double* positions_m, const std::int32_t* tet) {
  double p[4][3];
  for (int k = 0; k < 4; ++k) {
    for (int d = 0; d < 3; ++d) p[k][d] = positions_m[3 * tet[k] + d];
  }
  // Outward area normals; face k is the one opposite vertex k.
  double normal[4][3];
  double length[4];
  for (int k = 0; k < 4; ++k) {
    const double* a = p[(k + 1) % 4];
    const double* b = p[(k + 2) % 4];
    const double* c = p[(k + 3) % 4];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double* n = normal[k];
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
    const double toward_k = n[0] * (p[k][0] - a[0]) + n[1] * (p[k][1] - a[1]) + n[2] * (p[k][2] - a[2]);
    if (toward_k > 0.0) {
      for (int d = 0; d < 3; ++d) n[d] = -n[d];
    }
    length[k] = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  }
  constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
  DihedralRange range{180.0, 0.0};
  for (int k = 0; k < 4; ++k) {
    for (int l = k + 1; l < 4; ++l) {
      // Dihedral angle at the edge shared by faces k and l: cos = -n_k . n_l / (|n_k| |n_l|)
      const double c =
          -(normal[k][0] * normal[l][0] + normal[k][1] * normal[l][1] + normal[k][2] * normal[l][2]) /
          (length[k] * length[l]);
      const double angle = std::acos(std::clamp(c, -1.0, 1.0)) * kRadToDeg;
      range.min_deg = std::min(range.min_deg, angle);
      range.max_deg = std::max(range.max_deg, angle);
    }
  }
  return range;
}

double tet_radius_edge_ratio(const double* positions_m, const std::int32_t* tet) {
  const double* p0 = positions_m + 3 * tet[0];
  double e[3][3];  // edges from p0
  for (int k = 0; k < 3; ++k) {
    for (int d = 0; d < 3; ++d) e[k][d] = positions_m[3 * tet[k + 1] + d] - p0[d];
  }
  auto cross = [](const double* a, const double* b, double* out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
  };
  auto dot = [](const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  double vw[3], wu[3], uv[3];
  cross(e[1], e[2], vw);
  cross(e[2], e[0], wu);
  cross(e[0], e[1], uv);
  // Circumcentre offset from p0: (|u|^2 (v x w) + |v|^2 (w x u) + |w|^2 (u x v)) / (2 u . (v x w))
  const double denom = 2.0 * dot(e[0], vw);
  double centre[3];
  for (int d = 0; d < 3; ++d) {
    centre[d] = (dot(e[0], e[0]) * vw[d] + dot(e[1], e[1]) * wu[d] + dot(e[2], e[2]) * uv[d]) / denom;
  }
  const double circumradius = std::sqrt(dot(centre, centre));
  double shortest_sq = std::min({dot(e[0], e[0]), dot(e[1], e[1]), dot(e[2], e[2])});
  for (int a = 1; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      double d2 = 0.0;
      for (int d = 0; d < 3; ++d) {
        const double diff = positions_m[3 * tet[a] + d] - positions_m[3 * tet[b] + d];
        d2 += diff * diff;
      }
      shortest_sq = std::min(shortest_sq, d2);
    }
  }
  return circumradius / std::sqrt(shortest_sq);
}

void mark_surface_vertices(TetMesh& mesh) {
  const std::size_t num_tets = mesh.num_tets();
  // Every face as its sorted vertex triple; a boundary face occurs once.
  std::vector<std::array<std::int32_t, 3>> faces;
  faces.reserve(4 * num_tets);
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = &mesh.tets[4 * t];
    for (int skip = 0; skip < 4; ++skip) {
      std::array<std::int32_t, 3> f{};
      int k = 0;
      for (int i = 0; i < 4; ++i) {
        if (i != skip) f[k++] = v[i];
      }
      std::sort(f.begin(), f.end());
      faces.push_back(f);
    }
  }
  std::sort(faces.begin(), faces.end());
  mesh.on_surface.assign(mesh.num_vertices(), 0);
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j - i == 1) {
      for (std::int32_t v : faces[i]) mesh.on_surface[static_cast<std::size_t>(v)] = 1;
    }
    i = j;
  }
}

}  // namespace cellflow::mesh
