// Colouring of a tetrahedral mesh for race-free parallel scatter: groups of
// consecutive tets, greedily coloured so that no two groups of a colour share
// a vertex (used by the tangent assembly of cellflow::elastic).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace cellflow::mesh {

// Groups of `group_size` consecutive tetrahedra (group g = tets [g s, g s + s))
// coloured such that no two groups of one colour share a vertex (greedy, in
// order): a colour can be scattered in parallel without races. Groups of
// colour c are order[offsets[c] .. offsets[c + 1]). With group_size 1 the
// groups are single tets; larger groups give fewer colours (fewer barriers)
// and keep each thread streaming through consecutive tets.
struct TetColouring {
  std::int64_t group_size = 1;
  std::vector<std::int32_t> order;
  std::vector<std::int64_t> offsets;
  std::size_t num_colours() const { return offsets.empty() ? 0 : offsets.size() - 1; }
};
TetColouring colour_tets(std::span<const std::int32_t> tets, std::size_t num_vertices,
                         std::int64_t group_size = 1);

}  // namespace cellflow::mesh
