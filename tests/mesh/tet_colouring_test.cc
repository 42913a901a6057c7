// colour_tets on a structured box: every group is coloured once, and no two
// groups of one colour share a vertex.
#include "physics/mesh/tet_colouring.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "physics/mesh/tet_mesh.h"
#include "tests/elastic/box_mesh.h"

namespace cellflow::mesh {
namespace {

using elastic::testing::make_box_mesh;

// The box of the elastic tests (tests/elastic/elastic_test_util.h); only its
// connectivity matters here.
constexpr double kBoxSize = 10e-6;

TEST(TetColouring, NoTwoGroupsOfAColourShareAVertex) {
  const TetMesh mesh = make_box_mesh(6, 5, 4, kBoxSize, kBoxSize, kBoxSize);  // 720 tets
  const auto num_tets = static_cast<std::int64_t>(mesh.num_tets());
  for (const std::int64_t group_size : {1, 7, 64}) {
    const TetColouring colouring = colour_tets(mesh.tets, mesh.num_vertices(), group_size);
    const std::int64_t num_groups = (num_tets + group_size - 1) / group_size;
    ASSERT_EQ(static_cast<std::int64_t>(colouring.order.size()), num_groups);
    std::vector<int> seen_group(num_groups, 0);
    for (std::size_t c = 0; c < colouring.num_colours(); ++c) {
      std::vector<int> used(mesh.num_vertices(), -1);
      for (std::int64_t k = colouring.offsets[c]; k < colouring.offsets[c + 1]; ++k) {
        const std::int32_t g = colouring.order[k];
        ++seen_group[g];
        for (std::int64_t t = g * group_size; t < std::min(num_tets, (g + 1) * group_size); ++t) {
          for (int a = 0; a < 4; ++a) {
            int& owner = used[mesh.tets[4 * t + a]];
            EXPECT_TRUE(owner == -1 || owner == g) << "colour " << c << " groups " << owner << " and " << g;
            owner = g;
          }
        }
      }
    }
    for (const int count : seen_group) EXPECT_EQ(count, 1);
  }
}

}  // namespace
}  // namespace cellflow::mesh
