#include "physics/contact/surface_triangles.h"

#include <algorithm>
#include <array>

namespace cellflow::contact {

std::vector<std::int32_t> boundary_triangles(std::span<const std::int32_t> tets, const double* positions_m) {
  struct Face {
    std::array<std::int32_t, 3> sorted;
    std::array<std::int32_t, 3> vertices;  // as in the tet
    std::int32_t opposite;
  };
  // the faces of tet (a b c d), each with the vertex it does not contain
  constexpr int kFaces[4][4] = {{1, 2, 3, 0}, {0, 3, 2, 1}, {0, 1, 3, 2}, {0, 2, 1, 3}};
  std::vector<Face> faces;
  faces.reserve(tets.size());
  for (std::size_t t = 0; t + 3 < tets.size(); t += 4) {
    for (const auto& f : kFaces) {
      Face face{{}, {tets[t + f[0]], tets[t + f[1]], tets[t + f[2]]}, tets[t + f[3]]};
      face.sorted = face.vertices;
      std::sort(face.sorted.begin(), face.sorted.end());
      faces.push_back(face);
    }
  }
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) { return a.sorted < b.sorted; });
  std::vector<std::int32_t> out;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].sorted == faces[i].sorted) ++j;
    if (j - i == 1) {
      std::array<std::int32_t, 3> v = faces[i].vertices;
      const double* p0 = positions_m + 3 * static_cast<std::size_t>(v[0]);
      const double* p1 = positions_m + 3 * static_cast<std::size_t>(v[1]);
      const double* p2 = positions_m + 3 * static_cast<std::size_t>(v[2]);
      const double* po = positions_m + 3 * static_cast<std::size_t>(faces[i].opposite);
      double e1[3], e2[3], eo[3];
      for (int k = 0; k < 3; ++k) {
        e1[k] = p1[k] - p0[k];
        e2[k] = p2[k] - p0[k];
        eo[k] = po[k] - p0[k];
      }
      const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                           e1[0] * e2[1] - e1[1] * e2[0]};
      // outward: away from the tet's fourth vertex
      if (n[0] * eo[0] + n[1] * eo[1] + n[2] * eo[2] > 0.0) std::swap(v[1], v[2]);
      out.insert(out.end(), v.begin(), v.end());
    }
    i = j;
  }
  return out;
}

}  // namespace cellflow::contact
