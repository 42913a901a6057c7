// Bad input table: every invalid field of the quasi-static scenes is refused
// with kInvalidArgument (or the mesh reader's error) and a message that names
// the field path; nothing crashes and nothing is silently defaulted.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <string>

#include "physics/mesh/sphere_mesh.h"
#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::scenes {
namespace {

constexpr double kRadius = 8.6e-6;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

CompressionParams good_compression() {
  CompressionParams p;
  p.cell.radius_m = kRadius;
  p.cell.material = {.youngs_modulus_pa = 150.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 0.5};
  p.cell.target_vertex_count = 300;
  p.max_deformation = 0.5;
  p.load_points = 4;
  return p;
}

IndentationParams good_indentation() {
  IndentationParams p;
  p.cell = good_compression().cell;
  p.probe_radius_m = 5e-6;
  p.max_indentation_m = 2e-6;
  p.load_points = 4;
  return p;
}

struct BadCompression {
  const char* name;
  std::function<void(CompressionParams&)> edit;
  const char* field;  // must appear in the message
};

class CompressionBadInput : public ::testing::TestWithParam<BadCompression> {};

TEST_P(CompressionBadInput, IsRefusedNamingTheField) {
  CompressionParams p = good_compression();
  GetParam().edit(p);
  const Status s = validate(p);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.to_string();
  EXPECT_NE(s.message().find(GetParam().field), std::string::npos) << s.message();
  // the scene refuses it the same way, before any work, with an empty curve
  const QuasiStaticResult r = run_compression(p);
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(r.curve.empty());
}

INSTANTIATE_TEST_SUITE_P(
    Table, CompressionBadInput,
    ::testing::Values(
        BadCompression{"E_zero", [](auto& p) { p.cell.material.youngs_modulus_pa = 0; },
                       "compression.cell.material.youngs_modulus_pa"},
        BadCompression{"E_negative", [](auto& p) { p.cell.material.youngs_modulus_pa = -5; },
                       "compression.cell.material.youngs_modulus_pa"},
        BadCompression{"E_nan", [](auto& p) { p.cell.material.youngs_modulus_pa = kNaN; },
                       "compression.cell.material.youngs_modulus_pa"},
        BadCompression{"nu_half", [](auto& p) { p.cell.material.poisson_ratio = 0.5; },
                       "compression.cell.material.poisson_ratio"},
        BadCompression{"nu_minus_one", [](auto& p) { p.cell.material.poisson_ratio = -1.0; },
                       "compression.cell.material.poisson_ratio"},
        BadCompression{"w_above_one", [](auto& p) { p.cell.material.mooney_rivlin_w = 1.01; },
                       "compression.cell.material.mooney_rivlin_w"},
        BadCompression{"w_negative", [](auto& p) { p.cell.material.mooney_rivlin_w = -0.1; },
                       "compression.cell.material.mooney_rivlin_w"},
        BadCompression{"R_zero", [](auto& p) { p.cell.radius_m = 0; }, "compression.cell.radius_m"},
        BadCompression{"R_negative", [](auto& p) { p.cell.radius_m = -1e-6; }, "compression.cell.radius_m"},
        BadCompression{"deformation_zero", [](auto& p) { p.max_deformation = 0; },
                       "compression.max_deformation"},
        BadCompression{"deformation_negative", [](auto& p) { p.max_deformation = -0.1; },
                       "compression.max_deformation"},
        BadCompression{"deformation_one", [](auto& p) { p.max_deformation = 1.0; },
                       "compression.max_deformation"},
        BadCompression{"deformation_above_supported", [](auto& p) { p.max_deformation = 0.91; },
                       "compression.max_deformation"},
        BadCompression{"load_points_zero", [](auto& p) { p.load_points = 0; }, "compression.load_points"},
        BadCompression{"vertices_too_few", [](auto& p) { p.cell.target_vertex_count = 199; },
                       "compression.cell.target_vertex_count"},
        BadCompression{"vertices_too_many", [](auto& p) { p.cell.target_vertex_count = 20001; },
                       "compression.cell.target_vertex_count"},
        BadCompression{"nucleus_radius_zero",
                       [](auto& p) {
                         p.cell.nucleus = cell::NucleusParams{0.0, p.cell.material};
                       },
                       "compression.cell.nucleus.radius_m"},
        BadCompression{"nucleus_radius_equal_R",
                       [](auto& p) {
                         p.cell.nucleus = cell::NucleusParams{kRadius, p.cell.material};
                       },
                       "compression.cell.nucleus.radius_m"},
        BadCompression{"nucleus_material",
                       [](auto& p) {
                         p.cell.nucleus = cell::NucleusParams{0.5 * kRadius, p.cell.material};
                         p.cell.nucleus->material.youngs_modulus_pa = 0;
                       },
                       "compression.cell.nucleus.material.youngs_modulus_pa"},
        BadCompression{"tolerance_zero", [](auto& p) { p.numerics.residual_tolerance = 0; },
                       "compression.numerics.residual_tolerance"},
        BadCompression{"tolerance_large", [](auto& p) { p.numerics.residual_tolerance = 0.1; },
                       "compression.numerics.residual_tolerance"},
        BadCompression{"newton_zero", [](auto& p) { p.numerics.max_newton_iterations = 0; },
                       "compression.numerics.max_newton_iterations"},
        BadCompression{"splits_negative", [](auto& p) { p.numerics.max_step_splits = -1; },
                       "compression.numerics.max_step_splits"},
        BadCompression{"splits_large", [](auto& p) { p.numerics.max_step_splits = 31; },
                       "compression.numerics.max_step_splits"},
        BadCompression{"stiffness_zero", [](auto& p) { p.numerics.contact_stiffness_n_per_m = 0.0; },
                       "compression.numerics.contact_stiffness_n_per_m"},
        BadCompression{"range_negative", [](auto& p) { p.numerics.contact_range_m = -1e-9; },
                       "compression.numerics.contact_range_m"},
        BadCompression{"range_too_large", [](auto& p) { p.numerics.contact_range_m = 0.2 * kRadius; },
                       "compression.numerics.contact_range_m"},
        BadCompression{"gap_tolerance_too_small",
                       [](auto& p) { p.numerics.contact_gap_tolerance_m = 1e-9 * kRadius; },
                       "compression.numerics.contact_gap_tolerance_m"},
        BadCompression{"gap_tolerance_too_large",
                       [](auto& p) { p.numerics.contact_gap_tolerance_m = 0.1 * kRadius; },
                       "compression.numerics.contact_gap_tolerance_m"},
        BadCompression{"pole_spacing_negative", [](auto& p) { p.numerics.pole_spacing_m = -1e-7; },
                       "compression.numerics.pole_spacing_m"},
        BadCompression{"pole_spacing_too_small", [](auto& p) { p.numerics.pole_spacing_m = 1e-4 * kRadius; },
                       "compression.numerics.pole_spacing_m"},
        BadCompression{"pole_spacing_nan", [](auto& p) { p.numerics.pole_spacing_m = std::nan(""); },
                       "compression.numerics.pole_spacing_m"},
        BadCompression{"pole_growth_small", [](auto& p) { p.numerics.pole_grading_growth = 0.05; },
                       "compression.numerics.pole_grading_growth"},
        BadCompression{"ring_jitter_negative", [](auto& p) { p.numerics.pole_ring_jitter = -0.1; },
                       "compression.numerics.pole_ring_jitter"},
        BadCompression{"ring_jitter_too_large", [](auto& p) { p.numerics.pole_ring_jitter = 1.5; },
                       "compression.numerics.pole_ring_jitter"},
        BadCompression{"ring_jitter_nan", [](auto& p) { p.numerics.pole_ring_jitter = std::nan(""); },
                       "compression.numerics.pole_ring_jitter"},
        BadCompression{"threads_negative", [](auto& p) { p.numerics.threads = -1; },
                       "compression.numerics.threads"},
        BadCompression{"missing_mesh_file", [](auto& p) { p.cell.mesh_file = "/nonexistent/cell.msh"; },
                       "compression.cell.mesh_file"}),
    [](const ::testing::TestParamInfo<BadCompression>& param_info) {
      return std::string(param_info.param.name);
    });

TEST(CompressionBadInput, EveryViolationIsListed) {
  CompressionParams p = good_compression();
  p.cell.radius_m = -1;
  p.max_deformation = 2;
  p.load_points = 0;
  const Status s = validate(p);
  ASSERT_EQ(s.code(), StatusCode::kInvalidArgument);
  for (const char* field : {"cell.radius_m", "max_deformation", "load_points"}) {
    EXPECT_NE(s.message().find(field), std::string::npos) << s.message();
  }
  // the range is part of the message
  EXPECT_NE(s.message().find("(0, 0.9]"), std::string::npos) << s.message();
}

TEST(IndentationBadInput, ProbeAndIndentationFields) {
  struct Case {
    std::function<void(IndentationParams&)> edit;
    const char* field;
  };
  const Case cases[] = {
      {[](auto& p) { p.probe_radius_m = 0; }, "indentation.probe_radius_m"},
      {[](auto& p) { p.probe_radius_m = -1e-6; }, "indentation.probe_radius_m"},
      {[](auto& p) { p.max_indentation_m = 0; }, "indentation.max_indentation_m"},
      {[](auto& p) { p.max_indentation_m = 1.8 * kRadius; }, "indentation.max_indentation_m"},
      {[](auto& p) { p.load_points = -3; }, "indentation.load_points"},
      {[](auto& p) { p.cell.material.poisson_ratio = 0.7; }, "indentation.cell.material.poisson_ratio"},
  };
  for (const Case& c : cases) {
    IndentationParams p = good_indentation();
    c.edit(p);
    const Status s = validate(p);
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << c.field;
    EXPECT_NE(s.message().find(c.field), std::string::npos) << s.message();
    EXPECT_EQ(run_indentation(p).status.code(), StatusCode::kInvalidArgument);
  }
  EXPECT_TRUE(validate(good_indentation()).ok());
  EXPECT_TRUE(validate(good_compression()).ok());
}

class MeshFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        std::filesystem::temp_directory_path() /
        ("cellflow_scenes_validation_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
         "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
    mesh::SphereMeshOptions o;
    o.radius_m = kRadius;
    o.target_vertex_count = 300;
    sphere_ = mesh::make_sphere_mesh(o).value();
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string write(const mesh::TetMesh& m, const std::string& name) {
    const std::string path = (dir_ / name).string();
    EXPECT_TRUE(mesh::write_gmsh_msh(m, path).ok());
    return path;
  }
  std::filesystem::path dir_;
  mesh::TetMesh sphere_;
};

TEST_F(MeshFile, InvertedTetrahedronIsRefusedNamingTheFile) {
  mesh::TetMesh bad = sphere_;
  std::swap(bad.tets[4 * 11], bad.tets[4 * 11 + 1]);  // tet 11 turned inside out
  CompressionParams p = good_compression();
  p.cell.mesh_file = write(bad, "inverted.msh");
  const QuasiStaticResult r = run_compression(p);
  EXPECT_EQ(r.status.code(), StatusCode::kFailedPrecondition) << r.status.to_string();
  EXPECT_NE(r.status.message().find("compression.cell.mesh_file"), std::string::npos) << r.status.message();
  EXPECT_NE(r.status.message().find("inverted"), std::string::npos) << r.status.message();
  EXPECT_TRUE(r.curve.empty());
}

TEST_F(MeshFile, UnreadableContentIsRefused) {
  CompressionParams p = good_compression();
  const std::string path = (dir_ / "garbage.msh").string();
  { std::ofstream(path) << "this is not a mesh\n"; }
  p.cell.mesh_file = path;
  const QuasiStaticResult r = run_compression(p);
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument) << r.status.to_string();
  EXPECT_NE(r.status.message().find("compression.cell.mesh_file"), std::string::npos) << r.status.message();
}

TEST_F(MeshFile, MeshOfTheWrongSizeIsRefused) {
  mesh::TetMesh unit = sphere_;
  for (double& x : unit.positions_m) x /= kRadius;  // a unit sphere file, coordinates read in metres
  CompressionParams p = good_compression();
  p.cell.mesh_file = write(unit, "unit.msh");
  const QuasiStaticResult r = run_compression(p);
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status.message().find("compression.cell.radius_m"), std::string::npos) << r.status.message();
}

TEST_F(MeshFile, NucleusRequestedButAbsentIsRefused) {
  CompressionParams p = good_compression();
  p.cell.mesh_file = write(sphere_, "plain.msh");
  p.cell.nucleus = cell::NucleusParams{0.5 * kRadius, p.cell.material};
  const QuasiStaticResult r = run_compression(p);
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status.message().find("compression.cell.nucleus"), std::string::npos) << r.status.message();
}

TEST_F(MeshFile, GoodFileRunsLikeTheGeneratedMesh) {
  CompressionParams generated = good_compression();
  generated.max_deformation = 0.1;
  generated.load_points = 2;
  generated.numerics.threads = 1;
  CompressionParams from_file = generated;
  from_file.cell.mesh_file = write(sphere_, "sphere.msh");
  const QuasiStaticResult a = run_compression(generated);
  const QuasiStaticResult b = run_compression(from_file);
  ASSERT_TRUE(a.status.ok()) << a.status.to_string();
  ASSERT_TRUE(b.status.ok()) << b.status.to_string();
  ASSERT_EQ(a.curve.size(), 2u);
  ASSERT_EQ(b.curve.size(), 2u);
  // the file holds the same mesh (coordinates written with round-trip precision)
  EXPECT_NEAR(b.curve[1].force_n, a.curve[1].force_n, 1e-6 * a.curve[1].force_n);
}

// An uploaded mesh reaches the physics as bytes (cell.mesh_bytes): the same
// curve as the file, and errors name mesh_sha256 (never a path).
TEST_F(MeshFile, MeshBytesRunLikeTheFileAndErrorsNameTheHash) {
  CompressionParams from_file = good_compression();
  from_file.max_deformation = 0.1;
  from_file.load_points = 2;
  from_file.numerics.threads = 1;
  from_file.cell.mesh_file = write(sphere_, "sphere.msh");
  CompressionParams from_bytes = from_file;
  std::ifstream in(from_file.cell.mesh_file, std::ios::binary);
  from_bytes.cell.mesh_bytes = std::make_shared<const std::string>(std::istreambuf_iterator<char>(in),
                                                                   std::istreambuf_iterator<char>());
  from_bytes.cell.mesh_name = "mesh 0123abcd";
  from_bytes.cell.mesh_file = "/nonexistent/never-read.msh";  // the bytes take precedence
  const QuasiStaticResult a = run_compression(from_file);
  const QuasiStaticResult b = run_compression(from_bytes);
  ASSERT_TRUE(a.status.ok()) << a.status.to_string();
  ASSERT_TRUE(b.status.ok()) << b.status.to_string();
  ASSERT_EQ(b.curve.size(), 2u);
  EXPECT_EQ(b.curve[1].force_n, a.curve[1].force_n);

  CompressionParams garbage = good_compression();
  garbage.cell.mesh_bytes = std::make_shared<const std::string>("this is not a mesh\n");
  const QuasiStaticResult r = run_compression(garbage);
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument) << r.status.to_string();
  EXPECT_NE(r.status.message().find("compression.cell.mesh_sha256"), std::string::npos) << r.status.message();
  EXPECT_EQ(r.status.message().find("this is not"), std::string::npos) << r.status.message();
}

}  // namespace
}  // namespace cellflow::scenes
