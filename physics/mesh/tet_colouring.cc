// colour_tets: greedy colouring of groups of consecutive tetrahedra through
// the CSR lists of the groups around each vertex.
#include "physics/mesh/tet_colouring.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cellflow::mesh {

TetColouring colour_tets(std::span<const std::int32_t> tets, std::size_t num_vertices,
                         std::int64_t group_size) {
  const std::int64_t num_tets = static_cast<std::int64_t>(tets.size() / 4);
  group_size = std::max<std::int64_t>(1, group_size);
  const std::int64_t num_groups = (num_tets + group_size - 1) / group_size;
  // Groups around each vertex (CSR, each group once per vertex).
  std::vector<std::int64_t> offsets(num_vertices + 1, 0);
  std::vector<std::int64_t> last_group(num_vertices, -1);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    for (int a = 0; a < 4; ++a) {
      const std::int32_t v = tets[4 * t + a];
      if (last_group[v] != t / group_size) {
        last_group[v] = t / group_size;
        ++offsets[v + 1];
      }
    }
  }
  for (std::size_t v = 0; v < num_vertices; ++v) offsets[v + 1] += offsets[v];
  std::vector<std::int32_t> incident(static_cast<std::size_t>(offsets[num_vertices]));
  std::vector<std::int64_t> next(offsets.begin(), offsets.end() - 1);
  std::fill(last_group.begin(), last_group.end(), -1);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    for (int a = 0; a < 4; ++a) {
      const std::int32_t v = tets[4 * t + a];
      if (last_group[v] != t / group_size) {
        last_group[v] = t / group_size;
        incident[next[v]++] = static_cast<std::int32_t>(t / group_size);
      }
    }
  }
  // Greedy: each group takes the lowest colour not used by a group sharing a vertex.
  std::vector<std::int32_t> colour(num_groups, -1);
  std::vector<std::int64_t> blocked_by;  // per colour: the last group it was blocked for
  for (std::int64_t g = 0; g < num_groups; ++g) {
    const std::int64_t end = std::min(num_tets, (g + 1) * group_size);
    for (std::int64_t t = g * group_size; t < end; ++t) {
      for (int a = 0; a < 4; ++a) {
        const std::int32_t v = tets[4 * t + a];
        for (std::int64_t k = offsets[v]; k < offsets[v + 1]; ++k) {
          const std::int32_t other = colour[incident[k]];
          if (other >= 0) blocked_by[other] = g;
        }
      }
    }
    std::size_t c = 0;
    while (c < blocked_by.size() && blocked_by[c] == g) ++c;
    if (c == blocked_by.size()) blocked_by.push_back(-1);
    colour[g] = static_cast<std::int32_t>(c);
  }
  TetColouring result;
  result.group_size = group_size;
  result.offsets.assign(blocked_by.size() + 1, 0);
  for (const std::int32_t c : colour) ++result.offsets[c + 1];
  for (std::size_t c = 0; c < blocked_by.size(); ++c) result.offsets[c + 1] += result.offsets[c];
  result.order.resize(num_groups);
  std::vector<std::int64_t> next_slot(result.offsets.begin(), result.offsets.end() - 1);
  for (std::int64_t g = 0; g < num_groups; ++g)
    result.order[next_slot[colour[g]]++] = static_cast<std::int32_t>(g);
  return result;
}

}  // namespace cellflow::mesh
