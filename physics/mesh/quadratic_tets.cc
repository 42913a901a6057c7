#include "physics/mesh/quadratic_tets.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace cellflow::mesh {

namespace {

std::uint64_t edge_key(std::int32_t a, std::int32_t b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b));
  const auto hi = static_cast<std::uint64_t>(std::max(a, b));
  return (lo << 32) | hi;
}

// The mid-edge node of every edge of a quadratic mesh, sorted by edge key.
std::vector<std::pair<std::uint64_t, std::int32_t>> mid_edge_nodes(const TetMesh& mesh) {
  std::vector<std::pair<std::uint64_t, std::int32_t>> nodes;
  nodes.reserve(6 * mesh.num_tets());
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const std::int32_t* q = mesh.quadratic_tets.data() + 10 * t;
    for (int e = 0; e < 6; ++e)
      nodes.emplace_back(edge_key(q[kQuadraticTetEdges[e][0]], q[kQuadraticTetEdges[e][1]]), q[4 + e]);
  }
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

}  // namespace

void add_mid_edge_nodes(TetMesh& mesh, const MidEdgeProjection& projection) {
  if (!mesh.quadratic_tets.empty()) return;
  const std::size_t num_tets = mesh.num_tets();
  const std::size_t num_vertices = mesh.num_vertices();
  if (mesh.on_surface.size() != num_vertices) mesh.on_surface.resize(num_vertices, 0);
  // Every (edge, tet, local edge), sorted by edge: one node per run.
  struct EdgeUse {
    std::uint64_t key;
    std::int64_t slot;  // 10 t + 4 + e in quadratic_tets
  };
  std::vector<EdgeUse> uses;
  uses.reserve(6 * num_tets);
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = mesh.tets.data() + 4 * t;
    for (int e = 0; e < 6; ++e) {
      uses.push_back({edge_key(v[kQuadraticTetEdges[e][0]], v[kQuadraticTetEdges[e][1]]),
                      static_cast<std::int64_t>(10 * t + 4 + e)});
    }
  }
  std::sort(uses.begin(), uses.end(), [](const EdgeUse& a, const EdgeUse& b) { return a.key < b.key; });
  // Boundary edges: the edges of faces that belong to exactly one tet.
  std::vector<std::array<std::int32_t, 3>> faces;
  faces.reserve(4 * num_tets);
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = mesh.tets.data() + 4 * t;
    for (int skip = 0; skip < 4; ++skip) {
      std::array<std::int32_t, 3> f{};
      int n = 0;
      for (int a = 0; a < 4; ++a) {
        if (a != skip) f[n++] = v[a];
      }
      std::sort(f.begin(), f.end());
      faces.push_back(f);
    }
  }
  std::sort(faces.begin(), faces.end());
  std::vector<std::uint64_t> boundary_edges;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j - i == 1) {
      const auto& f = faces[i];
      boundary_edges.insert(boundary_edges.end(),
                            {edge_key(f[0], f[1]), edge_key(f[1], f[2]), edge_key(f[0], f[2])});
    }
    i = j;
  }
  std::sort(boundary_edges.begin(), boundary_edges.end());
  mesh.quadratic_tets.assign(10 * num_tets, -1);
  for (std::size_t t = 0; t < num_tets; ++t) {
    for (int a = 0; a < 4; ++a) mesh.quadratic_tets[10 * t + a] = mesh.tets[4 * t + a];
  }
  for (std::size_t i = 0; i < uses.size();) {
    const std::uint64_t key = uses[i].key;
    const auto a = static_cast<std::int32_t>(key >> 32);
    const auto b = static_cast<std::int32_t>(key & 0xffffffffu);
    const auto node = static_cast<std::int32_t>(mesh.num_vertices());
    const double* pa = mesh.positions_m.data() + 3 * static_cast<std::size_t>(a);
    const double* pb = mesh.positions_m.data() + 3 * static_cast<std::size_t>(b);
    double m[3] = {0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]), 0.5 * (pa[2] + pb[2])};
    const bool boundary = std::binary_search(boundary_edges.begin(), boundary_edges.end(), key);
    if (boundary && projection.sphere_centre_m) {
      // x_m = c + (|x_a - c| + |x_b - c|) / 2 (m - c) / |m - c|: on the sphere through the edge's ends
      const auto& c = *projection.sphere_centre_m;
      const auto distance = [&](const double* p) {
        return std::sqrt((p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                         (p[2] - c[2]) * (p[2] - c[2]));
      };
      const double radius = 0.5 * (distance(pa) + distance(pb));
      const double length = distance(m);
      if (length > 0.0) {
        for (int d = 0; d < 3; ++d) m[d] = c[d] + (m[d] - c[d]) * (radius / length);
      }
    }
    mesh.positions_m.insert(mesh.positions_m.end(), {m[0], m[1], m[2]});
    mesh.on_surface.push_back(boundary ? 1 : 0);
    for (; i < uses.size() && uses[i].key == key; ++i) mesh.quadratic_tets[uses[i].slot] = node;
  }
}

std::vector<std::int32_t> split_at_mid_edge_nodes(const TetMesh& mesh,
                                                  std::span<const std::int32_t> triangles) {
  const std::vector<std::pair<std::uint64_t, std::int32_t>> nodes = mid_edge_nodes(mesh);
  const auto node_of = [&](std::int32_t a, std::int32_t b) {
    const std::uint64_t key = edge_key(a, b);
    const auto it =
        std::lower_bound(nodes.begin(), nodes.end(), std::pair<std::uint64_t, std::int32_t>(key, -1));
    return it == nodes.end() || it->first != key ? -1 : it->second;
  };
  std::vector<std::int32_t> out;
  out.reserve(4 * triangles.size());
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const std::int32_t a = triangles[t], b = triangles[t + 1], c = triangles[t + 2];
    const std::int32_t ab = node_of(a, b), bc = node_of(b, c), ca = node_of(c, a);
    if (ab < 0 || bc < 0 || ca < 0) return {};
    out.insert(out.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
  }
  return out;
}

}  // namespace cellflow::mesh
