// Structured tetrahedral box for the elastic tests and benchmarks (no TetGen):
// nx x ny x nz hexahedra, each split into 6 tetrahedra around its main diagonal
// (Kuhn/Freudenthal split, conforming because every cube is split alike).
#pragma once

#include <array>
#include <cstdint>
#include <utility>

#include "physics/mesh/tet_mesh.h"

namespace cellflow::elastic::testing {

inline mesh::TetMesh make_box_mesh(int nx, int ny, int nz, double lx, double ly, double lz) {
  mesh::TetMesh mesh;
  const auto index = [&](int i, int j, int k) {
    return static_cast<std::int32_t>(i + (nx + 1) * (j + (ny + 1) * k));
  };
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) {
        mesh.positions_m.insert(mesh.positions_m.end(), {lx * i / nx, ly * j / ny, lz * k / nz});
        const bool boundary = i == 0 || j == 0 || k == 0 || i == nx || j == ny || k == nz;
        mesh.on_surface.push_back(boundary ? 1 : 0);
      }
    }
  }
  // The 6 monotone paths from corner 0 to corner 7 (bit 0 = x, 1 = y, 2 = z).
  constexpr std::array<std::array<int, 3>, 6> kAxisOrders = {
      {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  const double* x = nullptr;
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        const auto corner = [&](int bits) {
          return index(i + (bits & 1), j + ((bits >> 1) & 1), k + (bits >> 2));
        };
        for (const auto& axes : kAxisOrders) {
          const int c1 = 1 << axes[0];
          const int c2 = c1 | (1 << axes[1]);
          std::array<std::int32_t, 4> tet = {corner(0), corner(c1), corner(c2), corner(7)};
          // Positive orientation: det[x1 - x4, x2 - x4, x3 - x4] > 0 (paper eq. 11-12).
          x = mesh.positions_m.data();
          double e[3][3];
          for (int a = 0; a < 3; ++a) {
            for (int d = 0; d < 3; ++d) e[a][d] = x[3 * tet[a] + d] - x[3 * tet[3] + d];
          }
          const double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                             e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                             e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
          if (det < 0.0) std::swap(tet[0], tet[1]);
          mesh.tets.insert(mesh.tets.end(), tet.begin(), tet.end());
          mesh.tet_region.push_back(mesh::Region::kCytoplasm);
        }
      }
    }
  }
  return mesh;
}

}  // namespace cellflow::elastic::testing
