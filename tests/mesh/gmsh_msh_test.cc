// Gmsh MSH 4.1 ASCII import/export: round trip, orientation conversion,
// regions from physical groups, and the error paths.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"

namespace cellflow::mesh {
namespace {

std::string temp_path(const std::string& name) {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return ::testing::TempDir() + "cellflow_" + info->name() + "_" + name;
}

std::string write_text(const std::string& name, const std::string& text) {
  const std::string path = temp_path(name);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// Two unit-ish tets sharing the face (2, 3, 4): element 11 (nodes 1 2 3 4)
// and element 12 (nodes 2 3 4 5), both positive in Gmsh's convention
// det[x1 - x0, x2 - x0, x3 - x0] > 0 (volumes 1/6 and 1/3). Volume entity 1
// holds element 11, entity 2 element 12; physical groups are given per test.
std::string two_tet_file(const std::string& physical_names, const std::string& entity_physicals_1,
                         const std::string& entity_physicals_2,
                         const std::string& element_12 = "12 2 3 4 5") {
  return "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n" + physical_names +
         "$Entities\n0 0 1 2\n"
         "7 0 0 0 1 1 1 0 0\n"
         "1 0 0 0 1 1 1 " +
         entity_physicals_1 + " 0\n2 0 0 0 1 1 1 " + entity_physicals_2 +
         " 0\n"
         "$EndEntities\n"
         "$Nodes\n2 6 1 6\n"
         "3 1 0 5\n1\n2\n3\n4\n5\n"
         "0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n"
         "2 7 0 1\n6\n"  // a node no tetrahedron uses
         "5 5 5\n"
         "$EndNodes\n"
         "$Elements\n3 4 1 20\n"
         "2 7 2 1\n20 2 3 4\n"  // a triangle on surface 7: ignored
         "3 1 4 1\n11 1 2 3 4\n"
         "3 2 4 1\n" +
         element_12 +
         "\n"
         "$EndElements\n";
}

double total_volume(const TetMesh& mesh) {
  double v = 0.0;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t)
    v += tet_signed_volume(mesh.positions_m.data(), &mesh.tets[4 * t]);
  return v;
}

TEST(GmshMshTest, RoundTripPreservesMeshBitwise) {
  SphereMeshOptions options;
  options.radius_m = 5e-6;
  options.target_vertex_count = 500;
  options.nucleus_radius_m = 2.5e-6;
  const StatusOr<TetMesh> original = make_sphere_mesh(options);
  ASSERT_TRUE(original.ok()) << original.status().to_string();
  const std::string path = temp_path("sphere.msh");
  ASSERT_TRUE(write_gmsh_msh(*original, path).ok());
  const StatusOr<TetMesh> read = read_gmsh_msh(path);
  ASSERT_TRUE(read.ok()) << read.status().to_string();
  EXPECT_EQ(read->positions_m, original->positions_m);  // %.17g round-trips doubles exactly
  EXPECT_EQ(read->on_surface, original->on_surface);
  ASSERT_EQ(read->num_tets(), original->num_tets());
  // Tets are written grouped by region; compare as a multiset of (tet, region).
  auto keyed = [](const TetMesh& m) {
    std::vector<std::pair<std::array<std::int32_t, 4>, Region>> v;
    for (std::size_t t = 0; t < m.num_tets(); ++t) {
      v.push_back(
          {{m.tets[4 * t], m.tets[4 * t + 1], m.tets[4 * t + 2], m.tets[4 * t + 3]}, m.tet_region[t]});
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(keyed(*read), keyed(*original));
  std::remove(path.c_str());
}

TEST(GmshMshTest, ReadsTwoTetsConvertsOrientationAndScales) {
  const std::string path = write_text("two.msh", two_tet_file("", "1 1", "1 1"));
  const double scale = 1e-6;
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path, scale);
  ASSERT_TRUE(mesh.ok()) << mesh.status().to_string();
  EXPECT_EQ(mesh->num_vertices(), 5u);  // node 6 (unused) dropped, triangle ignored
  ASSERT_EQ(mesh->num_tets(), 2u);
  const double unit = scale * scale * scale;
  EXPECT_NEAR(tet_signed_volume(mesh->positions_m.data(), &mesh->tets[0]) / unit, 1.0 / 6.0, 1e-12);
  EXPECT_NEAR(tet_signed_volume(mesh->positions_m.data(), &mesh->tets[4]) / unit, 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(mesh->positions_m[3 * 4 + 2], 1e-6, 1e-20);  // node 5 z, scaled
  // Gmsh (g0, g1, g2, g3) -> (g1, g2, g3, g0): element 11 = nodes 1 2 3 4.
  EXPECT_EQ(mesh->tets[0], 1);
  EXPECT_EQ(mesh->tets[3], 0);
  // No nucleus group: both cytoplasm. All five vertices are on the boundary.
  EXPECT_EQ(mesh->tet_region[0], Region::kCytoplasm);
  EXPECT_EQ(mesh->tet_region[1], Region::kCytoplasm);
  for (std::uint8_t s : mesh->on_surface) EXPECT_EQ(s, 1);
  std::remove(path.c_str());
}

TEST(GmshMshTest, NucleusFromNamedPhysicalGroup) {
  const std::string names = "$PhysicalNames\n2\n3 1 \"cell\"\n3 5 \"nucleus\"\n$EndPhysicalNames\n";
  const std::string path = write_text("named.msh", two_tet_file(names, "1 1", "1 5"));
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status().to_string();
  EXPECT_EQ(mesh->tet_region[0], Region::kCytoplasm);
  EXPECT_EQ(mesh->tet_region[1], Region::kNucleus);
  EXPECT_NEAR(total_volume(*mesh), 0.5, 1e-12);
  std::remove(path.c_str());
}

TEST(GmshMshTest, NucleusFromUnnamedPhysicalTagTwo) {
  const std::string path = write_text("unnamed.msh", two_tet_file("", "1 1", "1 2"));
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status().to_string();
  EXPECT_EQ(mesh->tet_region[0], Region::kCytoplasm);
  EXPECT_EQ(mesh->tet_region[1], Region::kNucleus);
  std::remove(path.c_str());
}

TEST(GmshMshTest, PhysicalTagTwoNamedOtherwiseIsNotNucleus) {
  const std::string names = "$PhysicalNames\n1\n3 2 \"cortex\"\n$EndPhysicalNames\n";
  const std::string path = write_text("cortex.msh", two_tet_file(names, "1 1", "1 2"));
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_TRUE(mesh.ok()) << mesh.status().to_string();
  EXPECT_EQ(mesh->tet_region[1], Region::kCytoplasm);
  std::remove(path.c_str());
}

TEST(GmshMshTest, MissingFileIsNotFoundNamingPath) {
  const std::string path = temp_path("does_not_exist.msh");
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kNotFound);
  EXPECT_NE(mesh.status().message().find(path), std::string::npos) << mesh.status().message();
}

TEST(GmshMshTest, GarbledNodeLineIsInvalidArgumentWithLineNumber) {
  std::string text = two_tet_file("", "1 1", "1 1");
  // Line 20 is the coordinate line of node 3 ("0 1 0").
  const std::size_t at = text.find("\n0 1 0\n");
  text.replace(at, 7, "\n0 one 0\n");
  const std::string path = write_text("garbled.msh", text);
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(mesh.status().message().find(path + ":20:"), std::string::npos) << mesh.status().message();
  std::remove(path.c_str());
}

TEST(GmshMshTest, NotAnMshFileIsInvalidArgument) {
  const std::string path = write_text("text.msh", "hello world\n");
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(mesh.status().message().find(":1:"), std::string::npos) << mesh.status().message();
  std::remove(path.c_str());
}

TEST(GmshMshTest, TruncatedFileIsInvalidArgument) {
  const std::string full = two_tet_file("", "1 1", "1 1");
  const std::string path = write_text("truncated.msh", full.substr(0, full.find("$EndNodes") - 6));
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(mesh.status().message().find("$Nodes"), std::string::npos) << mesh.status().message();
  std::remove(path.c_str());
}

TEST(GmshMshTest, BinaryAndOldVersionsAreRejected) {
  for (const std::string header : {"4.1 1 8", "2.2 0 8"}) {
    std::string text = two_tet_file("", "1 1", "1 1");
    text.replace(text.find("4.1 0 8"), 7, header);
    const std::string path = write_text("format.msh", text);
    const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
    ASSERT_FALSE(mesh.ok()) << header;
    EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(mesh.status().message().find(":2:"), std::string::npos) << mesh.status().message();
    std::remove(path.c_str());
  }
}

TEST(GmshMshTest, InvertedTetIsFailedPreconditionNamingElement) {
  // Swapping two nodes of element 12 inverts it in Gmsh's convention.
  const std::string path = write_text("inverted.msh", two_tet_file("", "1 1", "1 1", "12 3 2 4 5"));
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(mesh.status().message().find("element 12 "), std::string::npos) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find("inverted"), std::string::npos) << mesh.status().message();
  std::remove(path.c_str());
}

TEST(GmshMshTest, DegenerateTetIsFailedPreconditionNamingElement) {
  // Element 12 made of nodes 1, 2, 3 and node 6 moved into their plane.
  std::string text = two_tet_file("", "1 1", "1 1", "12 1 2 3 6");
  text.replace(text.find("5 5 5\n"), 6, "2 3 0\n");  // node 6 in the z = 0 plane
  const std::string path = write_text("degenerate.msh", text);
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(mesh.status().message().find("element 12 "), std::string::npos) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find("degenerate"), std::string::npos) << mesh.status().message();
  std::remove(path.c_str());
}

TEST(GmshMshTest, NoTetrahedraIsFailedPrecondition) {
  std::string text = two_tet_file("", "1 1", "1 1");
  // Turn both tet blocks into 4-node quadrangles (type 3) on a surface.
  text.replace(text.find("3 1 4 1\n"), 8, "2 7 3 1\n");
  text.replace(text.find("3 2 4 1\n"), 8, "2 7 3 1\n");
  const std::string path = write_text("no_tets.msh", text);
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(mesh.status().message().find("no tetrahedra"), std::string::npos) << mesh.status().message();
  std::remove(path.c_str());
}

TEST(GmshMshTest, UnknownNodeIsInvalidArgument) {
  const std::string path = write_text("unknown_node.msh", two_tet_file("", "1 1", "1 1", "12 2 3 4 99"));
  const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(mesh.status().message().find("node 99"), std::string::npos) << mesh.status().message();
  std::remove(path.c_str());
}

}  // namespace
}  // namespace cellflow::mesh
