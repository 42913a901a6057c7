#include "physics/mesh/vertex_order.h"

#include <algorithm>
#include <boost/graph/adjacency_list.hpp>
#include <boost/graph/cuthill_mckee_ordering.hpp>
#include <cassert>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

namespace cellflow::mesh {

namespace {

// The reverse Cuthill-McKee order of the vertex graph (two vertices adjacent
// when they share a tet): new_index[old] for every vertex. It keeps a vertex's
// neighbours within the graph's bandwidth of it, and a contiguous range of it
// is a slab of level sets whose boundary with the next range is one level.
std::vector<std::int32_t> locality_vertex_order(const TetMesh& mesh) {
  using Graph = boost::adjacency_list<boost::vecS, boost::vecS, boost::undirectedS,
                                      boost::property<boost::vertex_color_t, boost::default_color_type,
                                                      boost::property<boost::vertex_degree_t, int>>>;
  using Vertex = boost::graph_traits<Graph>::vertex_descriptor;
  const std::size_t num_vertices = mesh.num_vertices();
  // Every tet edge, each once (an edge shared by several tets would otherwise
  // be a multi-edge and raise the degrees the order starts from).
  std::vector<std::pair<std::int32_t, std::int32_t>> edges;
  edges.reserve(6 * mesh.num_tets());
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const std::int32_t* v = &mesh.tets[4 * t];
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) edges.emplace_back(std::min(v[i], v[j]), std::max(v[i], v[j]));
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  Graph graph(num_vertices);
  for (const auto& [a, b] : edges) boost::add_edge(static_cast<Vertex>(a), static_cast<Vertex>(b), graph);
  std::vector<Vertex> order(num_vertices);
  // Reverse Cuthill-McKee from a pseudo-peripheral vertex of each component.
  boost::cuthill_mckee_ordering(graph, order.rbegin(), boost::get(boost::vertex_color, graph),
                                boost::make_degree_map(graph));
  std::vector<std::int32_t> new_index(num_vertices);
  for (std::size_t k = 0; k < num_vertices; ++k) new_index[order[k]] = static_cast<std::int32_t>(k);
  return new_index;
}

}  // namespace

void order_for_locality(TetMesh& mesh) {
  assert(mesh.quadratic_tets.empty());
  const std::size_t num_vertices = mesh.num_vertices();
  const std::size_t num_tets = mesh.num_tets();
  if (num_vertices == 0) return;
  const std::vector<std::int32_t> new_index = locality_vertex_order(mesh);
  std::vector<double> positions(mesh.positions_m.size());
  for (std::size_t v = 0; v < num_vertices; ++v) {
    std::copy_n(&mesh.positions_m[3 * v], 3, &positions[3 * static_cast<std::size_t>(new_index[v])]);
  }
  mesh.positions_m = std::move(positions);
  if (mesh.on_surface.size() == num_vertices) {
    std::vector<std::uint8_t> on_surface(num_vertices);
    for (std::size_t v = 0; v < num_vertices; ++v) on_surface[new_index[v]] = mesh.on_surface[v];
    mesh.on_surface = std::move(on_surface);
  }
  for (std::int32_t& v : mesh.tets) v = new_index[v];
  std::vector<std::int32_t> smallest(num_tets);
  for (std::size_t t = 0; t < num_tets; ++t) {
    smallest[t] = *std::min_element(&mesh.tets[4 * t], &mesh.tets[4 * t] + 4);
  }
  std::vector<std::size_t> tet_order(num_tets);
  std::iota(tet_order.begin(), tet_order.end(), std::size_t{0});
  std::stable_sort(tet_order.begin(), tet_order.end(),
                   [&](std::size_t a, std::size_t b) { return smallest[a] < smallest[b]; });
  std::vector<std::int32_t> tets(mesh.tets.size());
  std::vector<Region> regions(mesh.tet_region.size());
  for (std::size_t k = 0; k < num_tets; ++k) {
    std::copy_n(&mesh.tets[4 * tet_order[k]], 4, &tets[4 * k]);
    if (!regions.empty()) regions[k] = mesh.tet_region[tet_order[k]];
  }
  mesh.tets = std::move(tets);
  mesh.tet_region = std::move(regions);
}

}  // namespace cellflow::mesh
