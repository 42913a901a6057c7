// proto ShearFlowSpec -> scenes::ShearFlowParams: defaults of unset fields,
// the mapping of every set field, and a table of invalid specs with the field
// each refusal must name.
#include "jobs/shear_flow/shear_flow_spec.h"

#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <functional>
#include <string>

namespace cellflow::jobs {
namespace {

v1::ShearFlowSpec valid_spec() {
  v1::ShearFlowSpec spec;
  spec.mutable_cell()->set_radius_m(6e-6);
  spec.mutable_cell()->mutable_material()->set_youngs_modulus_pa(10.0);
  spec.set_capillary_number(0.05);
  return spec;
}

TEST(ShearFlowSpec, DefaultsOfUnsetFields) {
  const StatusOr<scenes::ShearFlowParams> p = to_params(valid_spec());
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  const scenes::ShearFlowParams defaults;
  EXPECT_DOUBLE_EQ(p->cell.radius_m, 6e-6);
  EXPECT_DOUBLE_EQ(p->cell.material.youngs_modulus_pa, 10.0);
  EXPECT_DOUBLE_EQ(p->cell.material.poisson_ratio, 0.48);
  EXPECT_DOUBLE_EQ(p->cell.material.mooney_rivlin_w, 1.0);
  EXPECT_EQ(p->cell.target_vertex_count, scenes::kFlowDefaultVertexCount);
  EXPECT_FALSE(p->cell.nucleus.has_value());
  EXPECT_DOUBLE_EQ(p->fluid_density_kg_m3, 1e3);
  EXPECT_DOUBLE_EQ(p->fluid_viscosity_pa_s, 1e-3);
  EXPECT_DOUBLE_EQ(p->capillary_number, 0.05);
  EXPECT_DOUBLE_EQ(p->shear_rate_per_s, 0.0);
  EXPECT_DOUBLE_EQ(p->numerics.cells_per_radius, defaults.numerics.cells_per_radius);
  EXPECT_DOUBLE_EQ(p->numerics.box_x_radii, 10.0);
  EXPECT_DOUBLE_EQ(p->numerics.box_y_radii, 15.0);
  EXPECT_DOUBLE_EQ(p->numerics.box_z_radii, 5.0);
  EXPECT_DOUBLE_EQ(p->numerics.target_reynolds_number, defaults.numerics.target_reynolds_number);
  EXPECT_EQ(p->numerics.ibm_kernel, ibm::Kernel::kPeskin4);
  EXPECT_EQ(p->numerics.single_precision, defaults.numerics.single_precision);
  EXPECT_TRUE(p->numerics.elastic_single_precision);
  EXPECT_DOUBLE_EQ(p->numerics.max_strain, defaults.numerics.max_strain);
  EXPECT_EQ(p->numerics.volumetric, elastic::VolumetricTerm::kPerTet);
  EXPECT_EQ(p->numerics.boundaries, scenes::ShearFlowBoundaries::kWalls);
  EXPECT_DOUBLE_EQ(p->viscosity_ratio, 1.0);
}

TEST(ShearFlowSpec, ViscosityRatioIsField7) {
  v1::ShearFlowSpec spec = valid_spec();
  spec.set_viscosity_ratio(0.05);
  const StatusOr<scenes::ShearFlowParams> p = to_params(spec);
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_DOUBLE_EQ(p->viscosity_ratio, 0.05);
}

TEST(ShearFlowSpec, MapsEverySetField) {
  v1::ShearFlowSpec spec = valid_spec();
  spec.mutable_cell()->set_target_vertex_count(500);
  spec.mutable_cell()->mutable_material()->set_poisson_ratio(0.45);
  spec.mutable_cell()->mutable_nucleus()->set_radius_m(3e-6);
  spec.mutable_cell()->mutable_nucleus()->mutable_material()->set_youngs_modulus_pa(50.0);
  spec.set_fluid_density_kg_m3(1050.0);
  spec.set_fluid_viscosity_pa_s(1.2e-3);
  spec.set_shear_rate_per_s(40.0);  // replaces the capillary number (oneof)
  v1::ShearFlowNumerics* n = spec.mutable_numerics();
  n->set_cells_per_radius(5.0);
  n->set_box_x_radii(8.0);
  n->set_box_y_radii(12.0);
  n->set_box_z_radii(6.0);
  n->set_relaxation_time(0.9);
  n->set_max_mach(0.15);
  n->set_max_time_s(2.0);
  n->set_steady_tolerance(1e-3);
  n->set_steady_window_strain(3.0);
  n->set_ibm_kernel("peskin3");
  n->set_single_precision(false);
  n->set_elastic_single_precision(false);
  n->set_sample_every_strain(0.2);
  n->set_snapshot_every_strain(0.5);
  n->set_fluid_snapshots(true);
  n->set_memory_limit_bytes(2e9);
  n->set_target_reynolds_number(0.05);
  n->set_max_strain(12.0);
  n->set_max_stiffness_ratio(1.5);
  n->set_hydrodynamic_radius_offset(0.25);
  n->set_volumetric_term(v1::VOLUMETRIC_TERM_NODAL_AVERAGE);
  n->set_boundaries("lees_edwards");
  const StatusOr<scenes::ShearFlowParams> p = to_params(spec);
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_EQ(p->cell.target_vertex_count, 500);
  EXPECT_DOUBLE_EQ(p->cell.material.poisson_ratio, 0.45);
  ASSERT_TRUE(p->cell.nucleus.has_value());
  EXPECT_DOUBLE_EQ(p->cell.nucleus->radius_m, 3e-6);
  EXPECT_DOUBLE_EQ(p->cell.nucleus->material.youngs_modulus_pa, 50.0);
  EXPECT_DOUBLE_EQ(p->fluid_density_kg_m3, 1050.0);
  EXPECT_DOUBLE_EQ(p->fluid_viscosity_pa_s, 1.2e-3);
  EXPECT_DOUBLE_EQ(p->shear_rate_per_s, 40.0);
  EXPECT_DOUBLE_EQ(p->capillary_number, 0.0);
  const scenes::ShearFlowNumerics& m = p->numerics;
  EXPECT_DOUBLE_EQ(m.cells_per_radius, 5.0);
  EXPECT_DOUBLE_EQ(m.box_x_radii, 8.0);
  EXPECT_DOUBLE_EQ(m.box_y_radii, 12.0);
  EXPECT_DOUBLE_EQ(m.box_z_radii, 6.0);
  EXPECT_DOUBLE_EQ(m.relaxation_time, 0.9);
  EXPECT_DOUBLE_EQ(m.max_mach, 0.15);
  EXPECT_DOUBLE_EQ(m.max_time_s, 2.0);
  EXPECT_DOUBLE_EQ(m.steady_tolerance, 1e-3);
  EXPECT_DOUBLE_EQ(m.steady_window_strain, 3.0);
  EXPECT_EQ(m.ibm_kernel, ibm::Kernel::kPeskin3);
  EXPECT_FALSE(m.single_precision);
  EXPECT_FALSE(m.elastic_single_precision);
  EXPECT_DOUBLE_EQ(m.sample_every_strain, 0.2);
  EXPECT_DOUBLE_EQ(m.snapshot_every_strain, 0.5);
  EXPECT_TRUE(m.fluid_snapshots);
  EXPECT_DOUBLE_EQ(m.memory_limit_bytes, 2e9);
  EXPECT_DOUBLE_EQ(m.target_reynolds_number, 0.05);
  EXPECT_DOUBLE_EQ(m.max_strain, 12.0);
  EXPECT_DOUBLE_EQ(m.max_stiffness_ratio, 1.5);
  EXPECT_DOUBLE_EQ(m.hydrodynamic_radius_offset, 0.25);
  EXPECT_EQ(m.volumetric, elastic::VolumetricTerm::kNodalAverage);
  EXPECT_EQ(m.boundaries, scenes::ShearFlowBoundaries::kLeesEdwards);
}

TEST(ShearFlowSpec, ReadsTheProtobufJsonMapping) {
  v1::ShearFlowSpec spec;
  const std::string json = R"({"cell": {"radiusM": 6e-6, "material": {"youngsModulusPa": 10}},
    "capillaryNumber": 0.1, "numerics": {"cellsPerRadius": 4, "ibmKernel": "peskin4"}})";
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(json, &spec).ok());
  const StatusOr<scenes::ShearFlowParams> p = to_params(spec);
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  EXPECT_DOUBLE_EQ(p->capillary_number, 0.1);
  EXPECT_DOUBLE_EQ(p->numerics.cells_per_radius, 4.0);
}

struct InvalidCase {
  const char* name;
  std::function<void(v1::ShearFlowSpec&)> mutate;
  StatusCode code;
  const char* field;  // must appear in the message
};

TEST(ShearFlowSpec, RefusalsNameTheField) {
  const InvalidCase cases[] = {
      {"no cell", [](v1::ShearFlowSpec& s) { s.clear_cell(); }, StatusCode::kInvalidArgument,
       "shear_flow.cell"},
      {"no material", [](v1::ShearFlowSpec& s) { s.mutable_cell()->clear_material(); },
       StatusCode::kInvalidArgument, "shear_flow.cell.material"},
      {"radius", [](v1::ShearFlowSpec& s) { s.mutable_cell()->set_radius_m(-1.0); },
       StatusCode::kInvalidArgument, "shear_flow.cell.radius_m"},
      {"poisson", [](v1::ShearFlowSpec& s) { s.mutable_cell()->mutable_material()->set_poisson_ratio(0.5); },
       StatusCode::kInvalidArgument, "shear_flow.cell.material.poisson_ratio"},
      {"vertices", [](v1::ShearFlowSpec& s) { s.mutable_cell()->set_target_vertex_count(50); },
       StatusCode::kInvalidArgument, "shear_flow.cell.target_vertex_count"},
      {"density", [](v1::ShearFlowSpec& s) { s.set_fluid_density_kg_m3(0.0); }, StatusCode::kInvalidArgument,
       "shear_flow.fluid_density_kg_m3"},
      {"viscosity", [](v1::ShearFlowSpec& s) { s.set_fluid_viscosity_pa_s(-1e-3); },
       StatusCode::kInvalidArgument, "shear_flow.fluid_viscosity_pa_s"},
      {"zero viscosity ratio", [](v1::ShearFlowSpec& s) { s.set_viscosity_ratio(0.0); },
       StatusCode::kInvalidArgument, "shear_flow.viscosity_ratio"},
      {"negative viscosity ratio", [](v1::ShearFlowSpec& s) { s.set_viscosity_ratio(-0.5); },
       StatusCode::kInvalidArgument, "shear_flow.viscosity_ratio"},
      {"no drive", [](v1::ShearFlowSpec& s) { s.clear_drive(); }, StatusCode::kInvalidArgument,
       "shear_flow.capillary_number"},
      {"zero shear rate", [](v1::ShearFlowSpec& s) { s.set_shear_rate_per_s(0.0); },
       StatusCode::kInvalidArgument, "shear_flow.shear_rate_per_s"},
      {"negative shear rate", [](v1::ShearFlowSpec& s) { s.set_shear_rate_per_s(-4.0); },
       StatusCode::kInvalidArgument, "shear_flow.shear_rate_per_s"},
      {"negative Ca", [](v1::ShearFlowSpec& s) { s.set_capillary_number(-0.1); },
       StatusCode::kInvalidArgument, "shear_flow.capillary_number"},
      {"cells per radius", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_cells_per_radius(1.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.cells_per_radius"},
      {"box x", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_box_x_radii(2.1); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.box_x_radii"},
      {"box y", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_box_y_radii(2.5); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.box_y_radii"},
      {"box z", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_box_z_radii(1.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.box_z_radii"},
      {"tau", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_relaxation_time(0.5); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.relaxation_time"},
      {"max mach", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_max_mach(0.5); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.max_mach"},
      {"mach exceeded",
       [](v1::ShearFlowSpec& s) {
         s.mutable_numerics()->set_target_reynolds_number(1.0);
         s.mutable_numerics()->set_cells_per_radius(4.0);
       },
       StatusCode::kInvalidArgument, "shear_flow.numerics.max_mach"},
      {"kernel", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_ibm_kernel("gauss"); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.ibm_kernel"},
      {"reynolds", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_target_reynolds_number(-0.1); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.target_reynolds_number"},
      {"tolerance", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_steady_tolerance(1.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.steady_tolerance"},
      {"window", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_steady_window_strain(0.1); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.steady_window_strain"},
      {"sample", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_sample_every_strain(0.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.sample_every_strain"},
      {"max strain", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_max_strain(-1.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.max_strain"},
      {"max time", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_max_time_s(-1.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.max_time_s"},
      {"snapshot", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_snapshot_every_strain(-1.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.snapshot_every_strain"},
      {"stiffness ratio", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_max_stiffness_ratio(-1.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.max_stiffness_ratio"},
      {"radius offset negative",
       [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_hydrodynamic_radius_offset(-0.5); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.hydrodynamic_radius_offset"},
      {"boundaries", [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_boundaries("lees-edwards"); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.boundaries"},
      {"radius offset large",
       [](v1::ShearFlowSpec& s) { s.mutable_numerics()->set_hydrodynamic_radius_offset(3.0); },
       StatusCode::kInvalidArgument, "shear_flow.numerics.hydrodynamic_radius_offset"},
      {"memory",
       [](v1::ShearFlowSpec& s) {
         s.mutable_numerics()->set_cells_per_radius(40.0);
         s.mutable_numerics()->set_target_reynolds_number(0.01);
         s.mutable_numerics()->set_memory_limit_bytes(1e9);
       },
       StatusCode::kResourceExhausted, "shear_flow.numerics.memory_limit_bytes"},
  };
  for (const InvalidCase& c : cases) {
    SCOPED_TRACE(c.name);
    v1::ShearFlowSpec spec = valid_spec();
    c.mutate(spec);
    const Status s = validate(spec);
    EXPECT_EQ(s.code(), c.code) << s.to_string();
    EXPECT_NE(s.message().find(c.field), std::string::npos) << s.to_string();
  }
  EXPECT_TRUE(validate(valid_spec()).ok());
}

}  // namespace
}  // namespace cellflow::jobs
