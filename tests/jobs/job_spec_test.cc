// Job spec edge: protobuf JSON in and out, defaults of unset optional fields,
// validation naming the field, the scenes that are not wired yet.
#include "jobs/job_spec.h"

#include <gtest/gtest.h>

#include <sstream>

#include "tools/run_job.h"

namespace cellflow::jobs {
namespace {

constexpr const char* kMinimalCompression = R"({
  "compression": {
    "cell": {"radiusM": 8.6e-6, "material": {"youngsModulusPa": 150}},
    "maxDeformation": 0.5
  }
})";

TEST(JobSpec, DefaultsOfUnsetOptionalFields) {
  StatusOr<v1::JobSpec> spec = job_spec_from_json(kMinimalCompression);
  ASSERT_TRUE(spec.ok()) << spec.status().to_string();
  StatusOr<scenes::CompressionParams> p = to_params(spec->compression());
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_EQ(p->cell.radius_m, 8.6e-6);
  EXPECT_EQ(p->cell.material.youngs_modulus_pa, 150.0);
  EXPECT_EQ(p->cell.material.poisson_ratio, 0.48);
  EXPECT_EQ(p->cell.material.mooney_rivlin_w, 1.0);
  EXPECT_EQ(p->cell.target_vertex_count, 3000);
  EXPECT_FALSE(p->cell.nucleus.has_value());
  EXPECT_TRUE(p->cell.mesh_file.empty());
  EXPECT_EQ(p->max_deformation, 0.5);
  EXPECT_EQ(p->load_points, 40);
  EXPECT_EQ(p->numerics.residual_tolerance, 1e-6);
  EXPECT_EQ(p->numerics.max_newton_iterations, 200);
  EXPECT_EQ(p->numerics.max_step_splits, 10);
  EXPECT_FALSE(p->numerics.contact_stiffness_n_per_m.has_value());
  EXPECT_FALSE(p->numerics.contact_range_m.has_value());
  EXPECT_EQ(p->numerics.volumetric, elastic::VolumetricTerm::kNodalAverage);
  EXPECT_TRUE(validate(*spec).ok());
}

TEST(JobSpec, ExplicitFieldsAreKept) {
  StatusOr<v1::JobSpec> spec = job_spec_from_json(R"({
    "indentation": {
      "cell": {"radiusM": 40e-6, "material": {"youngsModulusPa": 1000, "poissonRatio": 0.3, "mooneyRivlinW": 0},
               "nucleus": {"radiusM": 10e-6, "material": {"youngsModulusPa": 5000}},
               "targetVertexCount": 800},
      "probeRadiusM": 26.5e-6, "maxIndentationM": 8e-6, "loadPoints": 7,
      "numerics": {"residualTolerance": 1e-8, "maxNewtonIterations": 12, "maxStepSplits": 0,
                   "contactStiffnessNPerM": 0.5, "contactRangeM": 1e-8, "volumetricTerm": "VOLUMETRIC_TERM_PER_TET"}
    }
  })");
  ASSERT_TRUE(spec.ok()) << spec.status().to_string();
  StatusOr<scenes::IndentationParams> p = to_params(spec->indentation());
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_EQ(p->cell.material.poisson_ratio, 0.3);
  EXPECT_EQ(p->cell.material.mooney_rivlin_w, 0.0);  // explicit 0 is not "unset"
  ASSERT_TRUE(p->cell.nucleus.has_value());
  EXPECT_EQ(p->cell.nucleus->radius_m, 10e-6);
  EXPECT_EQ(p->cell.nucleus->material.youngs_modulus_pa, 5000.0);
  EXPECT_EQ(p->cell.nucleus->material.poisson_ratio, 0.48);
  EXPECT_EQ(p->cell.target_vertex_count, 800);
  EXPECT_EQ(p->probe_radius_m, 26.5e-6);
  EXPECT_EQ(p->max_indentation_m, 8e-6);
  EXPECT_EQ(p->load_points, 7);
  EXPECT_EQ(p->numerics.residual_tolerance, 1e-8);
  EXPECT_EQ(p->numerics.max_newton_iterations, 12);
  EXPECT_EQ(p->numerics.max_step_splits, 0);
  EXPECT_EQ(p->numerics.contact_stiffness_n_per_m.value(), 0.5);
  EXPECT_EQ(p->numerics.contact_range_m.value(), 1e-8);
  EXPECT_EQ(p->numerics.volumetric, elastic::VolumetricTerm::kPerTet);
}

TEST(JobSpec, UnknownAndMalformedJsonIsRefused) {
  const StatusOr<v1::JobSpec> unknown =
      job_spec_from_json(R"({"compression": {"cell": {"radiusM": 1e-5, "radius": 3}}})");
  EXPECT_EQ(unknown.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(unknown.status().message().find("radius"), std::string::npos) << unknown.status().message();
  EXPECT_EQ(job_spec_from_json("{\"compression\": ").status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(job_spec_from_json(R"({"compression": {"loadPoints": "many"}})").status().code(),
            StatusCode::kInvalidArgument);
}

TEST(JobSpec, ValidationNamesTheFieldPath) {
  struct Case {
    const char* json;
    const char* field;
  };
  const Case cases[] = {
      {R"({"compression": {"cell": {"radiusM": 8.6e-6, "material": {"youngsModulusPa": 150}}}})",
       "compression.max_deformation"},
      {R"({"compression": {"cell": {"radiusM": 8.6e-6, "material": {"youngsModulusPa": 150, "poissonRatio": 0.5}},
           "maxDeformation": 0.5}})",
       "compression.cell.material.poisson_ratio"},
      {R"({"compression": {"cell": {"radiusM": 8.6e-6, "material": {}}, "maxDeformation": 0.5}})",
       "compression.cell.material.youngs_modulus_pa"},
      {R"({"compression": {"cell": {"radiusM": 8.6e-6, "material": {"youngsModulusPa": 150}}, "maxDeformation": 0.5,
           "numerics": {"residualTolerance": 0}}})",
       "compression.numerics.residual_tolerance"},
      {R"({"compression": {"maxDeformation": 0.5}})", "compression.cell"},
      {R"({"indentation": {"cell": {"radiusM": 8.6e-6, "material": {"youngsModulusPa": 150}},
           "maxIndentationM": 1e-6}})",
       "indentation.probe_radius_m"},
      {R"({"indentation": {"cell": {"radiusM": 8.6e-6, "material": {"youngsModulusPa": 150}},
           "probeRadiusM": 5e-6, "maxIndentationM": 2e-5}})",
       "indentation.max_indentation_m"},
      {R"({"name": "nothing"})", "scene"},
      {R"({"shearFlow": {"cell": {"radiusM": 8.6e-6}}})", "shear_flow"},
  };
  for (const Case& c : cases) {
    StatusOr<v1::JobSpec> spec = job_spec_from_json(c.json);
    ASSERT_TRUE(spec.ok()) << c.json << ": " << spec.status().to_string();
    const Status s = validate(*spec);
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << c.json;
    EXPECT_NE(s.message().find(c.field), std::string::npos) << s.message();
  }
}

TEST(JobSpec, JsonRoundTrip) {
  StatusOr<v1::JobSpec> spec = job_spec_from_json(kMinimalCompression);
  ASSERT_TRUE(spec.ok());
  spec->set_name("round trip");
  spec->mutable_compression()->set_load_points(12);
  const std::string json = job_spec_to_json(*spec);
  EXPECT_NE(json.find("\"maxDeformation\": 0.5"), std::string::npos) << json;
  StatusOr<v1::JobSpec> back = job_spec_from_json(json);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->SerializeAsString(), spec->SerializeAsString());
}

TEST(RunJob, ExampleCompressionWritesTheCurve) {
  std::ostringstream csv;
  const tools::RunOutcome outcome =
      tools::run_spec_file(std::string(CELLFLOW_SOURCE_DIR) + "/examples/compression.json", csv, nullptr, 1);
  ASSERT_EQ(outcome.exit_code, tools::kExitOk) << outcome.status.to_string();
  std::istringstream lines(csv.str());
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, jobs::curve_csv_header());
  int rows = 0;
  double last_force = 0.0;
  while (std::getline(lines, line)) {
    ++rows;
    // point,deformation,displacement_m,force_n,...
    std::istringstream fields(line);
    std::string point, deformation, displacement, force;
    std::getline(fields, point, ',');
    std::getline(fields, deformation, ',');
    std::getline(fields, displacement, ',');
    std::getline(fields, force, ',');
    EXPECT_EQ(std::stoi(point), rows - 1);
    EXPECT_NEAR(std::stod(deformation), 0.05 * rows, 1e-12);
    EXPECT_GT(std::stod(force), last_force);
    last_force = std::stod(force);
  }
  EXPECT_EQ(rows, 10);  // examples/compression.json: 10 load points to 0.5
}

TEST(RunJob, ExitCodes) {
  std::ostringstream csv;
  EXPECT_EQ(tools::run_spec_file("/nonexistent/spec.json", csv, nullptr).exit_code, tools::kExitInvalidSpec);
  StatusOr<v1::JobSpec> spec = job_spec_from_json(kMinimalCompression);
  ASSERT_TRUE(spec.ok());
  spec->mutable_compression()->set_max_deformation(0.95);
  const tools::RunOutcome invalid = tools::run_job(*spec, csv, nullptr);
  EXPECT_EQ(invalid.exit_code, tools::kExitInvalidSpec);
  EXPECT_NE(invalid.status.message().find("compression.max_deformation"), std::string::npos);
  // a run that cannot converge: exit 3, the curve so far (header only) written
  spec->mutable_compression()->set_max_deformation(0.3);
  spec->mutable_compression()->set_load_points(3);
  spec->mutable_compression()->mutable_cell()->set_target_vertex_count(300);
  spec->mutable_compression()->mutable_numerics()->set_max_newton_iterations(1);
  spec->mutable_compression()->mutable_numerics()->set_max_step_splits(0);
  std::ostringstream failed_csv;
  const tools::RunOutcome failed = tools::run_job(*spec, failed_csv, nullptr, 1);
  EXPECT_EQ(failed.exit_code, tools::kExitNumericalFailure);
  EXPECT_EQ(failed_csv.str(), jobs::curve_csv_header() + "\n");
  EXPECT_NE(failed.status.message().find("load step 0"), std::string::npos) << failed.status.message();
}

TEST(JobSpec, SceneCellsAreEveryCellOfTheSceneWithItsFieldPath) {
  v1::JobSpec flow;
  flow.mutable_shear_flow()->mutable_cell()->set_radius_m(4e-6);
  std::string scene;
  std::vector<SceneCell> cells = scene_cells(flow, &scene);
  EXPECT_EQ(scene, "shear_flow");
  ASSERT_EQ(cells.size(), 1u);
  EXPECT_EQ(cells[0].field, "shear_flow.cell");
  EXPECT_EQ(cells[0].cell, flow.mutable_shear_flow()->mutable_cell());

  v1::JobSpec suspension;
  for (int k = 0; k < 3; ++k) suspension.mutable_suspension()->add_cells();
  suspension.mutable_suspension()->mutable_cells(0)->mutable_cell()->set_radius_m(4e-6);
  suspension.mutable_suspension()->mutable_cells(2)->mutable_cell()->set_mesh_file("x.msh");
  cells = scene_cells(suspension);  // the kind without a cell has none to check
  ASSERT_EQ(cells.size(), 2u);
  EXPECT_EQ(cells[0].field, "suspension.cells[0].cell");
  EXPECT_EQ(cells[1].field, "suspension.cells[2].cell");
  EXPECT_EQ(cells[1].cell->mesh_file(), "x.msh");

  v1::JobSpec none;
  EXPECT_TRUE(scene_cells(none).empty());
  v1::JobSpec no_cell;
  no_cell.mutable_compression()->set_max_deformation(0.1);
  EXPECT_TRUE(scene_cells(no_cell).empty());
}

}  // namespace
}  // namespace cellflow::jobs
